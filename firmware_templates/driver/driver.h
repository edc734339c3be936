/* The reference luminaire driver for protocol v2 (docs/protocol.md), ATmega328P at 16 MHz.
 * EEPROM memory map (1,024 bytes; docs/firmware.md "Reference driver firmware"):
 *
 *   0x000  provisioning: magic "VLPK", bus address u16, 0 u16, serial 16 bytes (ASCII, NUL-padded),
 *          driver key 32 bytes (planner/flash/keys.py), CRC-32 of the 56 bytes before it (60 bytes)
 *   0x040  slot A image area (VLP_SLOT_BYTES)
 *   0x140  commit record A (52 bytes: docs/protocol.md section 5)
 *   0x174  slot B image area
 *   0x274  commit record B
 *   0x2A8  staging header (52 bytes: planner/flash/sim/memory.py)
 *   0x2DC  end; 0x2DC..0x3FF unused
 */
#ifndef VLP_DRIVER_H
#define VLP_DRIVER_H

#include <stdint.h>

#define VLP_CPU_HZ 16000000UL
#define VLP_BAUD 250000UL          /* exact at 16 MHz (UBRR 3); 115,200 would be 2.1 % off */
#define VLP_SLOT_BYTES 256u
#define VLP_MAX_BLOCK 128u
/* Time to program VLP_MAX_BLOCK bytes on the real chip: 3.4 ms per EEPROM byte (datasheet tWD_EEPROM). */
#define VLP_BLOCK_WRITE_US (VLP_MAX_BLOCK * 3400UL)
#define VLP_FIRMWARE_VERSION 0x0100u

#define EE_PROVISION 0x000u
#define EE_PROVISION_BYTES 60u
#define EE_SLOTS 0x040u
#define EE_RECORD_BYTES 52u
#define EE_AREA(slot) (EE_SLOTS + ((slot) - 1u) * (VLP_SLOT_BYTES + EE_RECORD_BYTES))
#define EE_RECORD(slot) (EE_AREA(slot) + VLP_SLOT_BYTES)
#define EE_HEADER (EE_SLOTS + 2u * (VLP_SLOT_BYTES + EE_RECORD_BYTES))
#define EE_END (EE_HEADER + EE_RECORD_BYTES)

/* Configuration image (planner/firmware/image.py, docs/firmware.md). */
#define IMG_BYTES 168u
#define IMG_NAME 12u
#define IMG_RATE_MHZ 48u
#define IMG_CHIP_COUNT 52u
#define IMG_CHIPS 56u
#define IMG_VERSION 120u
#define IMG_SIGNATURE 132u
#define IMG_CRC 164u
#define IMG_MAX_CHIPS 512u

/* protocol.c: boot and one received frame (COBS-decoded in place, answered on the UART). */
void driver_boot(void);
void driver_frame(uint8_t *frame, uint16_t n);

/* main.c: the hardware. */
void uart_send(const uint8_t *p, uint16_t n);  /* raw bytes, blocking */
/* Play chips [0, count) of chips (MSB first) every `ticks` clock cycles; count 0 = LED steady on. */
void modulator_play(const uint8_t *chips, uint16_t count, uint32_t ticks);

#endif /* VLP_DRIVER_H */
