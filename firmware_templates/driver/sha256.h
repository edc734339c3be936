/* SHA-256 (FIPS 180-4) and HMAC-SHA256 (RFC 2104), small enough for an ATmega328P.
 * Plain C99: the same file builds for the AVR (round constants in flash) and for the
 * host (tests compare it with Python's hashlib). Messages up to 2^32 - 1 bytes. */
#ifndef VLP_SHA256_H
#define VLP_SHA256_H

#include <stdint.h>

#define SHA256_BYTES 32u

typedef struct {
    uint32_t h[8];
    uint32_t length;   /* message bytes so far */
    uint8_t block[64];
    uint8_t fill;      /* bytes in block */
} sha256_ctx;

void sha256_init(sha256_ctx *ctx);
void sha256_update(sha256_ctx *ctx, const uint8_t *data, uint16_t n);
void sha256_final(sha256_ctx *ctx, uint8_t digest[SHA256_BYTES]);

/* HMAC-SHA256 with a key of at most 64 bytes: hmac_init, any number of hmac_update
 * (sha256_update on ctx->inner), then hmac_final. */
typedef struct {
    sha256_ctx inner;
    uint8_t key[64];
} hmac_ctx;

void hmac_init(hmac_ctx *ctx, const uint8_t *key, uint8_t key_bytes);
void hmac_final(hmac_ctx *ctx, uint8_t mac[SHA256_BYTES]);

#endif /* VLP_SHA256_H */
