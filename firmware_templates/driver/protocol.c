/* Protocol v2, driver side (docs/protocol.md), mirroring planner/flash/sim/driver.py: framing
 * checks, the answer cache (same seq, command and CRC: a retry), HELLO answering the host's challenge
 * with an HMAC-SHA256 under this driver's own key, BEGIN / WRITE / VERIFY / COMMIT, A/B slots in
 * EEPROM with the commit record written last, the staging header for resume, and the image checks
 * (hash, format, HMAC-SHA256 under this driver's own key, rollback). */
#include <avr/eeprom.h>
#include <avr/pgmspace.h>
#include <string.h>
#include "codec.h"
#include "driver.h"
#include "sha256.h"

enum { HELLO = 1, BEGIN, WRITE, VERIFY, COMMIT };
enum { OK = 0, BAD_REQUEST, OFFSET, TOO_LARGE, NOT_BEGUN, INCOMPLETE, HASH, IMAGE, AUTH, ROLLBACK, FLASH };

typedef struct { /* commit record and staging header share one shape: 48 bytes + CRC-32 */
    char magic[4];
    uint32_t word;    /* record: commit counter; header: staged slot (byte 0), bytes 1..3 zero */
    uint32_t length;
    uint32_t version;
    uint8_t sha[32];
    uint32_t crc;
} __attribute__((packed)) entry_t;

typedef struct {
    char magic[4];
    uint16_t address;
    uint16_t zero;
    char serial[16];
    uint8_t key[32];
    uint32_t crc;
} __attribute__((packed)) provision_t;

static provision_t me;
static uint8_t provisioned;
static uint8_t active_slot, staging_slot, have_staging, begun;
static entry_t active, staging;
static uint16_t staged;

/* The last request's seq, command and CRC, and its response packet (docs/protocol.md section 3). */
static uint8_t have_last, last_seq, last_cmd;
static uint32_t last_crc;
static uint8_t resp[112]; /* the longest answer: HELLO with its MAC, 7 + 99 + 4 bytes */
static const uint8_t hello_label[13] = "VLP hello v2"; /* and its NUL: wire.HELLO_MAC_LABEL */
static uint16_t resp_len;
static uint32_t detail;
static uint8_t image[IMG_BYTES];

static const char msg_bad[] PROGMEM = "bad request";
static const char msg_offset[] PROGMEM = "not the next offset";
static const char msg_large[] PROGMEM = "image exceeds the slot";
static const char msg_begun[] PROGMEM = "no BEGIN since commit or reset";
static const char msg_incomplete[] PROGMEM = "image incomplete";
static const char msg_hash[] PROGMEM = "staged bytes do not hash to the SHA-256";
static const char msg_image[] PROGMEM = "not a configuration image this driver plays";
static const char msg_auth[] PROGMEM = "signature is not this driver's HMAC-SHA256";
static const char msg_rollback[] PROGMEM = "older than the active image";
static const char msg_flash[] PROGMEM = "EEPROM did not read back";
static PGM_P const messages[] PROGMEM = {msg_bad, msg_offset, msg_large, msg_begun, msg_incomplete, msg_hash,
                                         msg_image, msg_auth, msg_rollback, msg_flash};

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void put32(uint8_t *p, uint32_t v)
{
    memcpy(p, &v, 4); /* the AVR is little-endian, as the wire */
}

/* EEPROM access: avr-libc's update functions skip bytes that already hold the value. */
static uint32_t eeprom_crc(uint16_t addr, uint16_t n)
{
    uint8_t chunk[32];
    uint32_t crc = CRC32_START;
    while (n) {
        uint8_t k = n > sizeof chunk ? sizeof chunk : (uint8_t)n;
        eeprom_read_block(chunk, (const void *)addr, k);
        crc = crc32_add(crc, chunk, k);
        addr += k;
        n -= k;
    }
    return crc32_end(crc);
}

static void eeprom_sha(uint16_t addr, uint16_t n, uint8_t digest[32])
{
    uint8_t chunk[32];
    sha256_ctx ctx;
    sha256_init(&ctx);
    while (n) {
        uint8_t k = n > sizeof chunk ? sizeof chunk : (uint8_t)n;
        eeprom_read_block(chunk, (const void *)addr, k);
        sha256_update(&ctx, chunk, k);
        addr += k;
        n -= k;
    }
    sha256_final(&ctx, digest);
}

static void eeprom_erase(uint16_t addr, uint16_t n)
{
    while (n--) {
        eeprom_update_byte((uint8_t *)addr++, 0xFF);
    }
}

static uint8_t read_entry(uint16_t addr, const char *magic, entry_t *e)
{
    eeprom_read_block(e, (const void *)addr, sizeof *e);
    return memcmp(e->magic, magic, 4) == 0 && crc32_end(crc32_add(CRC32_START, (const uint8_t *)e, 48)) == e->crc;
}

static void seal(entry_t *e, const char *magic)
{
    memcpy(e->magic, magic, 4);
    e->crc = crc32_end(crc32_add(CRC32_START, (const uint8_t *)e, 48));
}

/* Timer cycles per chip for a rate in mHz: round(16 MHz / rate), ties up (planner chip_timer). */
static uint32_t chip_ticks(uint32_t millihz)
{
    return (uint32_t)((2ULL * VLP_CPU_HZ * 1000ULL + millihz) / (2ULL * millihz));
}

static void play_active(void)
{
    if (!active_slot) {
        modulator_play(0, 0, 0);
        return;
    }
    eeprom_read_block(image, (const void *)EE_AREA(active_slot), IMG_BYTES);
    modulator_play(image + IMG_CHIPS, (uint16_t)(image[IMG_CHIP_COUNT] | (image[IMG_CHIP_COUNT + 1] << 8)),
                   chip_ticks(le32(image + IMG_RATE_MHZ)));
}

/* Active slot and staging state as the EEPROM holds them; no BEGIN in progress (sim: _load). */
static void load(void)
{
    entry_t e;
    uint8_t slot, digest[32];
    begun = 0;
    active_slot = 0;
    for (slot = 1; slot <= 2; ++slot) {
        if (read_entry(EE_RECORD(slot), "VLPS", &e) && e.length <= VLP_SLOT_BYTES) {
            eeprom_sha(EE_AREA(slot), (uint16_t)e.length, digest);
            if (memcmp(digest, e.sha, 32) == 0 && (!active_slot || e.word > active.word)) {
                active = e;
                active_slot = slot;
            }
        }
    }
    staging_slot = active_slot == 1 ? 2 : 1;
    have_staging = read_entry(EE_HEADER, "VLPH", &e) && e.word == staging_slot && e.length > 0 &&
                   e.length <= VLP_SLOT_BYTES;
    staged = 0;
    if (have_staging) {
        uint16_t i;
        staging = e;
        for (i = (uint16_t)e.length; i > 0; --i) { /* staged = up to the last byte that is not erased */
            if (eeprom_read_byte((const uint8_t *)(EE_AREA(staging_slot) + i - 1u)) != 0xFF) {
                staged = i;
                break;
            }
        }
    }
}

void driver_boot(void)
{
    eeprom_read_block(&me, (const void *)EE_PROVISION, sizeof me);
    provisioned = memcmp(me.magic, "VLPK", 4) == 0 &&
                  crc32_end(crc32_add(CRC32_START, (const uint8_t *)&me, EE_PROVISION_BYTES - 4u)) == me.crc &&
                  me.address >= 1 && me.address <= 0xFFFE;
    have_last = 0;
    load();
    play_active();
}

/* Commands: each fills resp + 7 with its payload and returns its length, or sets detail and
 * returns a negative status. */
/* HMAC-SHA256 under this driver's key of label | nonce | address u16 | the 67 bytes of fields, into mac. */
static __attribute__((noinline)) void hello_mac(const uint8_t *nonce, const uint8_t *fields, uint8_t *mac)
{
    hmac_ctx h;
    uint8_t address[2];
    address[0] = (uint8_t)me.address;
    address[1] = (uint8_t)(me.address >> 8);
    hmac_init(&h, me.key, sizeof me.key);
    sha256_update(&h.inner, hello_label, sizeof hello_label);
    sha256_update(&h.inner, nonce, 16);
    sha256_update(&h.inner, address, 2);
    sha256_update(&h.inner, fields, 67);
    hmac_final(&h, mac);
}

/* An empty HELLO: the 67 bytes of fields; a challenge (16-byte nonce): the fields and their MAC. */
static int16_t cmd_hello(const uint8_t *in, uint16_t n, uint8_t *out)
{
    if (n != 0 && n != 16) {
        return -BAD_REQUEST;
    }
    out[0] = 2;
    out[1] = 0x07; /* A/B slots, resume, HMAC-SHA256 */
    out[2] = (uint8_t)VLP_MAX_BLOCK;
    out[3] = (uint8_t)(VLP_MAX_BLOCK >> 8);
    put32(out + 4, VLP_SLOT_BYTES);
    put32(out + 8, VLP_BLOCK_WRITE_US);
    out[12] = (uint8_t)VLP_FIRMWARE_VERSION;
    out[13] = (uint8_t)(VLP_FIRMWARE_VERSION >> 8);
    memcpy(out + 14, me.serial, 16);
    out[30] = active_slot;
    put32(out + 31, active_slot ? active.version : 0);
    if (active_slot) {
        memcpy(out + 35, active.sha, 32);
    } else {
        memset(out + 35, 0, 32);
    }
    if (n == 0) {
        return 67;
    }
    hello_mac(in, out, out + 67);
    return 99;
}

static int16_t cmd_begin(const uint8_t *in, uint16_t n, uint8_t *out)
{
    entry_t wanted;
    uint32_t length, version;
    if (n != 41) {
        return -BAD_REQUEST;
    }
    length = le32(in);
    version = le32(in + 4);
    if (length > VLP_SLOT_BYTES) {
        detail = VLP_SLOT_BYTES;
        return -TOO_LARGE;
    }
    if (length == 0 || in[40] > 1) {
        return -BAD_REQUEST;
    }
    memset(&wanted, 0, sizeof wanted);
    wanted.word = staging_slot;
    wanted.length = length;
    wanted.version = version;
    memcpy(wanted.sha, in + 8, 32);
    seal(&wanted, "VLPH");
    if (in[40] || !have_staging || memcmp(&wanted, &staging, sizeof wanted) != 0) {
        have_staging = 0;
        staged = 0;
        eeprom_erase(EE_HEADER, EE_RECORD_BYTES); /* no resume until the new header is whole */
        eeprom_erase(EE_RECORD(staging_slot), EE_RECORD_BYTES); /* the old fallback is invalid from here on */
        eeprom_erase(EE_AREA(staging_slot), VLP_SLOT_BYTES);
        eeprom_update_block(&wanted, (void *)EE_HEADER, sizeof wanted);
        staging = wanted;
        have_staging = 1;
    }
    begun = 1;
    put32(out, staged);
    put32(out + 4, eeprom_crc(EE_AREA(staging_slot), staged));
    return 8;
}

static int16_t cmd_write(const uint8_t *in, uint16_t n, uint8_t *out)
{
    uint32_t offset;
    uint16_t size;
    if (n < 5 || n > 4u + VLP_MAX_BLOCK) {
        return -BAD_REQUEST;
    }
    if (!begun || !have_staging) {
        return -NOT_BEGUN;
    }
    offset = le32(in);
    size = n - 4u;
    if (offset <= staged && offset + size <= staged) { /* (offset first: no u32 wrap-around) */
        put32(out, staged); /* a retransmission: already there */
        return 4;
    }
    if (offset != staged) {
        detail = staged;
        return -OFFSET;
    }
    if (offset + size > staging.length) {
        return -BAD_REQUEST;
    }
    eeprom_update_block(in + 4, (void *)(EE_AREA(staging_slot) + (uint16_t)offset), size);
    staged += size;
    put32(out, staged);
    return 4;
}

static int16_t cmd_verify(uint16_t n, uint8_t *out)
{
    if (n != 0) {
        return -BAD_REQUEST;
    }
    if (!begun || !have_staging) {
        return -NOT_BEGUN;
    }
    put32(out, staged);
    eeprom_sha(EE_AREA(staging_slot), staged, out + 4); /* read back from the EEPROM */
    return 36;
}

/* Python's strict UTF-8 (what parse_config_image accepts): no overlongs, surrogates or > U+10FFFF. */
static uint8_t utf8_ok(const uint8_t *s, uint8_t n)
{
    uint8_t i = 0;
    while (i < n) {
        uint8_t c = s[i], need, lo = 0x80, hi = 0xBF, k;
        if (c < 0x80) {
            ++i;
            continue;
        }
        if (c >= 0xC2 && c <= 0xDF) {
            need = 1;
        } else if (c >= 0xE0 && c <= 0xEF) {
            need = 2;
            lo = c == 0xE0 ? 0xA0 : 0x80;
            hi = c == 0xED ? 0x9F : 0xBF;
        } else if (c >= 0xF0 && c <= 0xF4) {
            need = 3;
            lo = c == 0xF0 ? 0x90 : 0x80;
            hi = c == 0xF4 ? 0x8F : 0xBF;
        } else {
            return 0;
        }
        if ((uint16_t)i + need >= n) {
            return 0;
        }
        for (k = 1; k <= need; ++k) {
            uint8_t t = s[i + k];
            if (t < (k == 1 ? lo : 0x80) || t > (k == 1 ? hi : 0xBF)) {
                return 0;
            }
        }
        i = (uint8_t)(i + need + 1u);
    }
    return 1;
}

/* parse_config_image's checks, plus what this driver's timer can play. */
static uint8_t image_ok(uint32_t length)
{
    uint16_t count = (uint16_t)(image[IMG_CHIP_COUNT] | (image[IMG_CHIP_COUNT + 1] << 8));
    uint8_t name = 32;
    uint32_t ticks;
    if (length != IMG_BYTES || memcmp(image, "VLPC", 4) != 0 || image[4] != 1 || image[5] != 0 ||
        image[6] != 12 || image[7] != 0 || le32(image + 8) != IMG_BYTES ||
        crc32_end(crc32_add(CRC32_START, image, IMG_CRC)) != le32(image + IMG_CRC) ||
        count < 1 || count > IMG_MAX_CHIPS || le32(image + IMG_RATE_MHZ) == 0) {
        return 0;
    }
    while (name > 0 && image[IMG_NAME + name - 1u] == 0) {
        --name;
    }
    ticks = chip_ticks(le32(image + IMG_RATE_MHZ));
    return utf8_ok(image + IMG_NAME, name) && ticks >= 160 && ticks <= 65536UL; /* 244 Hz .. 100 kHz */
}

/* HMAC-SHA256 under this driver's key over image[0, 132) equals image[132, 164), compared in constant
 * time. Not inlined, so its 200 bytes of stack are free again before the commit reloads the slots. */
static __attribute__((noinline)) uint8_t signed_for_me(void)
{
    uint8_t mac[32], diff = 0, i;
    hmac_ctx h;
    hmac_init(&h, me.key, sizeof me.key);
    sha256_update(&h.inner, image, IMG_SIGNATURE);
    hmac_final(&h, mac);
    for (i = 0; i < 32; ++i) {
        diff |= (uint8_t)(mac[i] ^ image[IMG_SIGNATURE + i]);
    }
    return diff == 0;
}

/* The commit record of the staged slot, written last and read back; 0 if it did not read back. */
static __attribute__((noinline)) uint8_t write_record(const uint8_t digest[32], uint32_t version)
{
    entry_t record;
    uint16_t where = EE_RECORD(staging_slot), i;
    record.word = active_slot ? active.word + 1u : 1u;
    record.length = staging.length;
    record.version = version;
    memcpy(record.sha, digest, 32);
    seal(&record, "VLPS");
    eeprom_update_block(&record, (void *)where, sizeof record); /* last: the slot is valid with its final byte */
    for (i = 0; i < sizeof record; ++i) {
        if (eeprom_read_byte((const uint8_t *)(where + i)) != ((const uint8_t *)&record)[i]) {
            detail = where + i;
            return 0;
        }
    }
    return 1;
}

static int16_t cmd_commit(const uint8_t *in, uint16_t n, uint8_t *out)
{
    uint8_t digest[32];
    uint32_t version;
    if (n != 32) {
        return -BAD_REQUEST;
    }
    if (!begun || !have_staging) {
        return -NOT_BEGUN;
    }
    if (staged < staging.length) {
        detail = staged;
        return -INCOMPLETE;
    }
    eeprom_sha(EE_AREA(staging_slot), (uint16_t)staging.length, digest);
    if (memcmp(digest, staging.sha, 32) != 0 || memcmp(digest, in, 32) != 0) {
        return -HASH;
    }
    if (staging.length != IMG_BYTES) {
        return -IMAGE;
    }
    eeprom_read_block(image, (const void *)EE_AREA(staging_slot), IMG_BYTES);
    version = le32(image + IMG_VERSION);
    if (!image_ok(staging.length) || version != staging.version) {
        return -IMAGE;
    }
    if (!signed_for_me()) {
        return -AUTH;
    }
    if (active_slot && (version < active.version || (version == active.version && memcmp(digest, active.sha, 32)))) {
        detail = active.version;
        return -ROLLBACK;
    }
    if ((!active_slot || memcmp(digest, active.sha, 32) != 0) && !write_record(digest, version)) {
        return -FLASH;
    }
    load(); /* the new active slot as the EEPROM now holds it; a new BEGIN is needed */
    play_active();
    out[0] = active_slot;
    put32(out + 1, active_slot ? active.version : 0);
    return 5;
}

static void send_cobs(const uint8_t *p, uint16_t n) /* n < 254: one COBS block per zero */
{
    uint16_t i = 0, j;
    uint8_t code;
    for (;;) {
        for (j = i; j < n && p[j]; ++j) {
        }
        code = (uint8_t)(j - i + 1u);
        uart_send(&code, 1);
        uart_send(p + i, j - i);
        if (j >= n) {
            break;
        }
        i = j + 1u;
    }
    code = 0;
    uart_send(&code, 1);
}

void driver_frame(uint8_t *frame, uint16_t n)
{
    int decoded = cobs_decode(frame, n);
    uint16_t length, size, to;
    int16_t result;
    uint32_t crc;
    uint8_t cmd, *out = resp + 7;

    if (!provisioned || decoded < 11) {
        return;
    }
    size = (uint16_t)decoded;
    length = (uint16_t)(frame[5] | (frame[6] << 8));
    if (crc32_end(crc32_add(CRC32_START, frame, size - 4u)) != le32(frame + size - 4u) || length != size - 11u) {
        return; /* damaged: never answered, the host retries */
    }
    to = (uint16_t)(frame[0] | (frame[1] << 8));
    if ((frame[2] & 0x01) || (to != me.address && to != 0xFFFFu)) {
        return; /* a response, or another driver's request */
    }
    cmd = frame[4];
    crc = le32(frame + size - 4u);
    if (!(have_last && frame[3] == last_seq && cmd == last_cmd && crc == last_crc)) {
        const uint8_t *in = frame + 7;
        detail = 0;
        switch (cmd) {
        case HELLO: result = cmd_hello(in, length, out); break;
        case BEGIN: result = cmd_begin(in, length, out); break;
        case WRITE: result = cmd_write(in, length, out); break;
        case VERIFY: result = cmd_verify(length, out); break;
        case COMMIT: result = cmd_commit(in, length, out); break;
        default: result = -BAD_REQUEST; break;
        }
        resp[2] = 0x01;
        if (result < 0) {
            PGM_P msg = (PGM_P)pgm_read_ptr(&messages[-result - 1]);
            uint8_t len = (uint8_t)strlen_P(msg);
            resp[2] = 0x03;
            out[0] = (uint8_t)-result;
            put32(out + 1, detail);
            memcpy_P(out + 5, msg, len);
            result = (int16_t)(5 + len);
        }
        resp[0] = (uint8_t)me.address;
        resp[1] = (uint8_t)(me.address >> 8);
        resp[3] = frame[3];
        resp[4] = cmd;
        resp[5] = (uint8_t)result;
        resp[6] = 0;
        put32(resp + 7 + result, crc32_end(crc32_add(CRC32_START, resp, 7u + (uint16_t)result)));
        resp_len = (uint16_t)(11 + result);
        have_last = 1;
        last_seq = frame[3];
        last_cmd = cmd;
        last_crc = crc;
    }
    send_cobs(resp, resp_len);
}
