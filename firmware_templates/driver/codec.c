/* CRC-32 and COBS: see codec.h. Bitwise CRC (no table: 4 bytes of flash, not 1 KB). */
#include "codec.h"

uint32_t crc32_add(uint32_t crc, const uint8_t *p, uint16_t n)
{
    uint8_t bit;
    while (n--) {
        crc ^= *p++;
        for (bit = 0; bit < 8; ++bit) {
            crc = (crc >> 1) ^ (0xEDB88320UL & (0UL - (crc & 1UL)));
        }
    }
    return crc;
}

int cobs_decode(uint8_t *buf, uint16_t n)
{
    uint16_t r = 0, w = 0;
    while (r < n) {
        uint8_t code = buf[r++], i;
        if (code == 0) {
            return -1;
        }
        for (i = 1; i < code; ++i) {
            if (r >= n || buf[r] == 0) {
                return -1;
            }
            buf[w++] = buf[r++];
        }
        if (code != 0xFF && r < n) {
            buf[w++] = 0;
        }
    }
    return (int)w;
}
