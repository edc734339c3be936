/* Host build of the driver's codec and hash code, for tests/test_driver_avr.py:
 *   host_test sha HEX          -> SHA-256 of the bytes, hex
 *   host_test hmac KEYHEX HEX  -> HMAC-SHA256, hex
 *   host_test crc HEX          -> CRC-32/ISO-HDLC, hex
 *   host_test cobs HEX         -> COBS-decoded bytes, hex, or "error" */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "codec.h"
#include "sha256.h"

static uint16_t unhex(const char *text, uint8_t *out)
{
    uint16_t n = 0;
    unsigned int byte;
    while (text[0] && text[1] && sscanf(text, "%2x", &byte) == 1) {
        out[n++] = (uint8_t)byte;
        text += 2;
    }
    return n;
}

static void print_hex(const uint8_t *p, uint16_t n)
{
    uint16_t i;
    for (i = 0; i < n; ++i) {
        printf("%02x", p[i]);
    }
    printf("\n");
}

int main(int argc, char **argv)
{
    static uint8_t data[4096], key[64];
    uint8_t digest[SHA256_BYTES];
    uint16_t n;

    if (argc == 3 && !strcmp(argv[1], "sha")) {
        sha256_ctx ctx;
        n = unhex(argv[2], data);
        sha256_init(&ctx);
        sha256_update(&ctx, data, n);
        sha256_final(&ctx, digest);
        print_hex(digest, sizeof digest);
    } else if (argc == 4 && !strcmp(argv[1], "hmac")) {
        hmac_ctx ctx;
        uint16_t k = unhex(argv[2], key);
        n = unhex(argv[3], data);
        hmac_init(&ctx, key, (uint8_t)k);
        sha256_update(&ctx.inner, data, n);
        hmac_final(&ctx, digest);
        print_hex(digest, sizeof digest);
    } else if (argc == 3 && !strcmp(argv[1], "crc")) {
        n = unhex(argv[2], data);
        printf("%08lx\n", (unsigned long)crc32_end(crc32_add(CRC32_START, data, n)));
    } else if (argc == 3 && !strcmp(argv[1], "cobs")) {
        int m;
        n = unhex(argv[2], data);
        m = cobs_decode(data, n);
        if (m < 0) {
            printf("error\n");
        } else {
            print_hex(data, (uint16_t)m);
        }
    } else {
        fprintf(stderr, "usage: host_test sha HEX | hmac KEYHEX HEX | crc HEX | cobs HEX\n");
        return 2;
    }
    return 0;
}
