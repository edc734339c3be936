/* SHA-256 and HMAC-SHA256: see sha256.h. Byte-oriented, a 16-word rolling message
 * schedule (64 bytes of RAM), round constants in program memory on the AVR. */
#include <string.h>
#include "sha256.h"

#ifdef __AVR__
#include <avr/pgmspace.h>
#define K_AT(i) pgm_read_dword(&K[i])
#define MEMCPY_CONST memcpy_P
#else
#define PROGMEM
#define K_AT(i) K[i]
#define MEMCPY_CONST memcpy
#endif

static const uint32_t K[64] PROGMEM = {
    0x428a2f98UL, 0x71374491UL, 0xb5c0fbcfUL, 0xe9b5dba5UL, 0x3956c25bUL, 0x59f111f1UL, 0x923f82a4UL, 0xab1c5ed5UL,
    0xd807aa98UL, 0x12835b01UL, 0x243185beUL, 0x550c7dc3UL, 0x72be5d74UL, 0x80deb1feUL, 0x9bdc06a7UL, 0xc19bf174UL,
    0xe49b69c1UL, 0xefbe4786UL, 0x0fc19dc6UL, 0x240ca1ccUL, 0x2de92c6fUL, 0x4a7484aaUL, 0x5cb0a9dcUL, 0x76f988daUL,
    0x983e5152UL, 0xa831c66dUL, 0xb00327c8UL, 0xbf597fc7UL, 0xc6e00bf3UL, 0xd5a79147UL, 0x06ca6351UL, 0x14292967UL,
    0x27b70a85UL, 0x2e1b2138UL, 0x4d2c6dfcUL, 0x53380d13UL, 0x650a7354UL, 0x766a0abbUL, 0x81c2c92eUL, 0x92722c85UL,
    0xa2bfe8a1UL, 0xa81a664bUL, 0xc24b8b70UL, 0xc76c51a3UL, 0xd192e819UL, 0xd6990624UL, 0xf40e3585UL, 0x106aa070UL,
    0x19a4c116UL, 0x1e376c08UL, 0x2748774cUL, 0x34b0bcb5UL, 0x391c0cb3UL, 0x4ed8aa4aUL, 0x5b9cca4fUL, 0x682e6ff3UL,
    0x748f82eeUL, 0x78a5636fUL, 0x84c87814UL, 0x8cc70208UL, 0x90befffaUL, 0xa4506cebUL, 0xbef9a3f7UL, 0xc67178f2UL,
};

static const uint32_t H0[8] PROGMEM = {
    0x6a09e667UL, 0xbb67ae85UL, 0x3c6ef372UL, 0xa54ff53aUL, 0x510e527fUL, 0x9b05688cUL, 0x1f83d9abUL, 0x5be0cd19UL,
};

/* Rotate right by n (a constant once inlined): whole bytes first, which avr-gcc does with register
 * moves, then at most four single-bit steps either way. Bit shifts by a variable count compile to
 * loops of 32-bit shifts on the AVR; this is four times faster there. */
static inline __attribute__((always_inline)) uint32_t ror(uint32_t x, uint8_t n)
{
    uint8_t bytes = (uint8_t)((n + 3u) / 8u), bits = n % 8u;
    if (bytes & 3u) {
        x = (x >> (8u * (bytes & 3u))) | (x << (32u - 8u * (bytes & 3u)));
    }
    if (bits <= 4u) {
        while (bits--) {
            x = (x & 1u) ? (x >> 1) | 0x80000000UL : x >> 1;
        }
    } else {
        for (bits = 8u - bits; bits--;) {
            x = (x & 0x80000000UL) ? (x << 1) | 1u : x << 1;
        }
    }
    return x;
}

static inline __attribute__((always_inline)) uint32_t shr(uint32_t x, uint8_t n)
{
    x >>= 8u * (n / 8u);
    return x >> (n % 8u);
}

static void compress(sha256_ctx *ctx)
{
    uint32_t w[16], v[8], t1, t2;
    uint8_t i;

    for (i = 0; i < 16; ++i) {
        const uint8_t *p = ctx->block + 4u * i;
        w[i] = ((uint32_t)p[0] << 24) | ((uint32_t)p[1] << 16) | ((uint32_t)p[2] << 8) | p[3];
    }
    memcpy(v, ctx->h, sizeof v);
    for (i = 0; i < 64; ++i) {
        uint32_t wi;
        if (i < 16) {
            wi = w[i];
        } else {
            uint32_t a = w[(i + 1u) & 15u], b = w[(i + 14u) & 15u];
            wi = w[i & 15u] += (ror(a, 7) ^ ror(a, 18) ^ shr(a, 3)) + w[(i + 9u) & 15u]
                               + (ror(b, 17) ^ ror(b, 19) ^ shr(b, 10));
        }
        t1 = v[7] + (ror(v[4], 6) ^ ror(v[4], 11) ^ ror(v[4], 25)) + ((v[4] & v[5]) ^ (~v[4] & v[6])) + K_AT(i) + wi;
        t2 = (ror(v[0], 2) ^ ror(v[0], 13) ^ ror(v[0], 22)) + ((v[0] & v[1]) ^ (v[0] & v[2]) ^ (v[1] & v[2]));
        memmove(v + 1, v, 7 * sizeof v[0]);
        v[4] += t1;
        v[0] = t1 + t2;
    }
    for (i = 0; i < 8; ++i) {
        ctx->h[i] += v[i];
    }
}

void sha256_init(sha256_ctx *ctx)
{
    MEMCPY_CONST(ctx->h, H0, sizeof ctx->h);
    ctx->length = 0;
    ctx->fill = 0;
}

void sha256_update(sha256_ctx *ctx, const uint8_t *data, uint16_t n)
{
    while (n--) {
        ctx->block[ctx->fill++] = *data++;
        ctx->length++;
        if (ctx->fill == 64u) {
            compress(ctx);
            ctx->fill = 0;
        }
    }
}

void sha256_final(sha256_ctx *ctx, uint8_t digest[SHA256_BYTES])
{
    uint32_t bits_hi = ctx->length >> 29, bits_lo = ctx->length << 3;
    uint8_t i;

    ctx->block[ctx->fill++] = 0x80u;
    if (ctx->fill > 56u) {
        memset(ctx->block + ctx->fill, 0, 64u - ctx->fill);
        compress(ctx);
        ctx->fill = 0;
    }
    memset(ctx->block + ctx->fill, 0, 56u - ctx->fill);
    for (i = 0; i < 4; ++i) {
        ctx->block[56u + i] = (uint8_t)(bits_hi >> (24u - 8u * i));
        ctx->block[60u + i] = (uint8_t)(bits_lo >> (24u - 8u * i));
    }
    compress(ctx);
    for (i = 0; i < 32; ++i) {
        digest[i] = (uint8_t)(ctx->h[i >> 2] >> (24u - 8u * (i & 3u)));
    }
}

static void keyed_start(sha256_ctx *sha, const uint8_t key[64], uint8_t pad)
{
    uint8_t i, b;
    sha256_init(sha);
    for (i = 0; i < 64; ++i) {
        b = key[i] ^ pad;
        sha256_update(sha, &b, 1);
    }
}

void hmac_init(hmac_ctx *ctx, const uint8_t *key, uint8_t key_bytes)
{
    memset(ctx->key, 0, sizeof ctx->key);
    memcpy(ctx->key, key, key_bytes > 64u ? 64u : key_bytes);
    keyed_start(&ctx->inner, ctx->key, 0x36u);
}

void hmac_final(hmac_ctx *ctx, uint8_t mac[SHA256_BYTES])
{
    uint8_t inner[SHA256_BYTES];
    sha256_final(&ctx->inner, inner);
    keyed_start(&ctx->inner, ctx->key, 0x5cu);
    sha256_update(&ctx->inner, inner, sizeof inner);
    sha256_final(&ctx->inner, mac);
}
