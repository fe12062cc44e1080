/* update.c - the §10 update session (update.h): YMODEM blocks into the staging slot. */
#include "crc.h"
#include "image.h"
#include "update.h"

/* Frame sizes, ID to CHK: header and data blocks have a fixed shape. */
#define ENTER_BYTES 5u                                   /* ID 03 FF FC CHK */
#define EOF_BYTES 6u                                     /* ID 04 FF FE 04 CHK */
#define HEADER_BYTES (7u + PROTO_UPDATE_HEADER_DATA + 3u)      /* LEN 0x88 */
#define DATA_BYTES PROTO_UPDATE_DATA_FRAME                   /* LEN 0xFF, 1031 + CHK */
#define OFF_TYPE 4u
#define OFF_NUM 5u
#define OFF_DATA 7u

_Static_assert(PROTO_UPDATE_BLOCK_DATA == HAL_FLASH_PAGE_BYTES, "data block n is staging page n-1");

bool update_is_frame(const uint8_t *buf, uint16_t len)
{
    return len >= ENTER_BYTES && buf[2] == 0xFFu &&
           (buf[3] == PROTO_UPDATE_SUB_ENTER || buf[3] == PROTO_UPDATE_SUB_BLOCK);
}

/* A header or data block of the right shape: LEN, block number and its complement, and
 * the CRC-16/XMODEM of its data (high byte first). */
static bool block_intact(const uint8_t *buf, uint16_t len, uint16_t want_len, uint8_t len_byte,
                         uint16_t data)
{
    if (len != want_len || buf[1] != len_byte ||
        buf[OFF_NUM] + buf[OFF_NUM + 1u] != 0xFF) /* n and ~n */
        return false;
    uint16_t crc = crc16_update(0, &buf[OFF_DATA], data);
    const uint8_t *c = &buf[OFF_DATA + data];
    return c[0] == (uint8_t)(crc >> 8) && c[1] == (uint8_t)crc;
}

static bool all_zero(const uint8_t *p, uint16_t n)
{
    uint8_t any = 0;
    while (n--)
        any |= *p++;
    return any == 0u;
}

/* The session is over, refused: CAN. */
static uint8_t cancel(struct update *u, uint8_t ans[2])
{
    u->state = UPDATE_IDLE;
    ans[0] = UPDATE_CAN;
    return UPDATE_ABANDONED;
}

/* Header block (type 1, number 0). Non-zero: the image length; all zero: end of batch. */
static uint8_t on_header(struct update *u, struct hal *hal, uint16_t model, const uint8_t *d,
                         uint8_t ans[2], uint8_t *n)
{
    if (all_zero(d, PROTO_UPDATE_HEADER_DATA)) {
        if (u->state != UPDATE_EOF) { /* an empty batch: nothing to install */
            u->state = UPDATE_IDLE;
            ans[0] = UPDATE_ACK;
            return UPDATE_ABANDONED;
        }
        struct image_info info;
        /* Bad CRC, truncated or not what the header said; or a flash error. */
        if (!image_valid(hal, HAL_PAGE_STAGING, model, &info) || info.length != u->length ||
            !hal_flash_program(hal, IMAGE_MARK_PAGE, IMAGE_MARK_OFFSET, IMAGE_MARK_SET) ||
            !image_marked(hal))
            return cancel(u, ans);
        u->state = UPDATE_IDLE;
        ans[0] = UPDATE_ACK;
        return UPDATE_RESTART;
    }
    if (u->state == UPDATE_ENTERED || (u->state == UPDATE_DATA && u->next == 1u)) {
        uint32_t length = ((uint32_t)d[0] << 24) | ((uint32_t)d[1] << 16) |
                          ((uint32_t)d[2] << 8) | d[3];
        /* Not an image for this slot; or the install mark of an earlier session, which
         * is cleared before anything is staged, stays set (a flash error). */
        if (length < IMAGE_MIN_BYTES || length > IMAGE_MAX_BYTES ||
            (image_marked(hal) && (!hal_flash_erase(hal, IMAGE_MARK_PAGE) || image_marked(hal))))
            return cancel(u, ans);
        u->length = length;
        u->blocks = (uint8_t)((length + PROTO_UPDATE_BLOCK_DATA - 1u) / PROTO_UPDATE_BLOCK_DATA);
        u->next = 1;
        u->state = UPDATE_DATA;
        ans[0] = UPDATE_ACK;
        ans[1] = UPDATE_READY;
        *n = 2;
        return UPDATE_GO_ON;
    }
    return cancel(u, ans); /* a second file: one image per session */
}

static uint8_t on_data(struct update *u, struct hal *hal, uint16_t model, uint8_t num,
                       const uint8_t *d, uint8_t ans[2])
{
    ans[0] = UPDATE_ACK;
    if (u->state != UPDATE_ENTERED && u->next > 1u && num == (uint8_t)(u->next - 1u))
        return UPDATE_GO_ON; /* our ACK was lost: acknowledge again, do not rewrite */
    if (u->state == UPDATE_DATA && num != u->next) {
        ans[0] = UPDATE_NAK;
        return UPDATE_GO_ON;
    }
    struct image_info info;
    bool ok = u->state == UPDATE_DATA && u->next <= u->blocks;
    if (ok && num == 1u) /* the info block: refuse another board's or a mislabelled image */
        ok = image_parse_info(d, &info) && info.model == model && info.length == u->length;
    if (ok) {
        /* The image's bytes only: the padding of the last block stays erased, so it can
         * never program the install mark at the end of the slot (a full-length image
         * padded with zeros did, and an abandoned session was then installed). */
        uint32_t left = u->length - (uint32_t)(num - 1u) * PROTO_UPDATE_BLOCK_DATA;
        uint16_t n = left < PROTO_UPDATE_BLOCK_DATA ? (uint16_t)((left + 1u) & ~1u)
                                                    : (uint16_t)PROTO_UPDATE_BLOCK_DATA;
        ok = image_write_page(hal, (uint8_t)(HAL_PAGE_STAGING + num - 1u), d, n);
    }
    if (!ok)
        return cancel(u, ans);
    u->next++;
    return UPDATE_GO_ON;
}

static uint8_t on_eof(struct update *u, uint8_t ans[2], uint8_t *n)
{
    if (u->state == UPDATE_EOF || (u->state == UPDATE_DATA && u->next > u->blocks)) {
        u->state = UPDATE_EOF;
        ans[0] = UPDATE_ACK;
        ans[1] = UPDATE_READY;
        *n = 2;
        return UPDATE_GO_ON;
    }
    return cancel(u, ans); /* truncated: fewer blocks than the header announced */
}

uint8_t update_frame(struct update *u, struct hal *hal, uint16_t model, const uint8_t *buf,
                     uint16_t len, bool chk_ok, uint32_t now_us, uint8_t ans[2], uint8_t *n)
{
    *n = 1;
    ans[0] = UPDATE_NAK; /* a damaged frame: the host sends it again */
    if (!chk_ok)
        return UPDATE_GO_ON;
    u->last_us = now_us;
    if (buf[3] == PROTO_UPDATE_SUB_ENTER) {
        if (len != ENTER_BYTES || buf[1] != 3u)
            return UPDATE_GO_ON;
        u->state = UPDATE_ENTERED;
        u->next = 1;
        ans[0] = UPDATE_READY;
        return UPDATE_STARTED;
    }
    if (len < EOF_BYTES)
        return UPDATE_GO_ON;
    bool header = buf[OFF_TYPE] == PROTO_UPDATE_TYPE_HEADER &&
                  block_intact(buf, len, HEADER_BYTES, (uint8_t)(HEADER_BYTES - 2u),
                               PROTO_UPDATE_HEADER_DATA) && buf[OFF_NUM] == 0u;
    if (u->state == UPDATE_IDLE) {
        /* No session. An end of batch is ACKed all the same: it is the host resending
         * the last frame of a session whose ACK it missed while the servo restarted. */
        ans[0] = header && all_zero(&buf[OFF_DATA], PROTO_UPDATE_HEADER_DATA) ? UPDATE_ACK : UPDATE_CAN;
        return UPDATE_GO_ON;
    }
    switch (buf[OFF_TYPE]) {
    case PROTO_UPDATE_TYPE_HEADER:
        if (!header)
            return UPDATE_GO_ON;
        return on_header(u, hal, model, &buf[OFF_DATA], ans, n);
    case PROTO_UPDATE_TYPE_DATA:
        if (!block_intact(buf, len, DATA_BYTES, 0xFFu, PROTO_UPDATE_BLOCK_DATA))
            return UPDATE_GO_ON;
        return on_data(u, hal, model, buf[OFF_NUM], &buf[OFF_DATA], ans);
    case PROTO_UPDATE_TYPE_EOF:
        if (len != EOF_BYTES || buf[1] != 4u)
            return UPDATE_GO_ON;
        return on_eof(u, ans, n);
    default:
        return UPDATE_GO_ON;
    }
}

bool update_active(struct update *u, uint32_t now_us)
{
    if (u->state != UPDATE_IDLE && now_us - u->last_us > UPDATE_TIMEOUT_US)
        u->state = UPDATE_IDLE;
    return u->state != UPDATE_IDLE;
}
