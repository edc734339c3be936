/* The wire's byte codecs (docs/protocol.md section 2): CRC-32/ISO-HDLC and COBS.
 * Plain C99, built for the AVR and for the host (tests). */
#ifndef VLP_CODEC_H
#define VLP_CODEC_H

#include <stdint.h>

#define CRC32_START 0xFFFFFFFFUL

/* crc32_end(crc32_add(CRC32_START, p, n)) is zlib's crc32(p); calls may be chained. */
uint32_t crc32_add(uint32_t crc, const uint8_t *p, uint16_t n);
#define crc32_end(crc) (~(uint32_t)(crc))

/* Decode the COBS frame buf[0..n) (no zero delimiter) in place; the decoded length, or -1
 * if the frame is not valid COBS (a zero byte, a code running past the end). */
int cobs_decode(uint8_t *buf, uint16_t n);

#endif /* VLP_CODEC_H */
