/* fuzz_update.c - the firmware update (PROTOCOL.md §10): arbitrary sequences of update
 * frames into the session (update.c, through loader_update_frame, which update mode and
 * the application's dispatcher share), power cuts, and the bootloader's install decision
 * at every power-up (boot_install, through servo_power_on: then the application or, with
 * no valid application, update mode).
 *
 * The harness builds the frames, so they can be right where a fuzzer would never get
 * them right by chance (LEN, block number and complement, CRC-16, the checksum), and
 * wrong on purpose where the input says; data blocks carry the pages of an image the
 * input describes (own model or another, any length, CRC-32 right or not).
 *
 * Input: byte 0 picks the board (% BOARD_COUNT, board_all) and, if the quotient is odd,
 * an application slot erased at the factory (the servo starts in update mode); then
 * operations, one byte o each, with operands (missing bytes read as 0); a frame goes
 * straight to loader_update_frame, or if o & 0x80 through the receiver (D5 5D first) to
 * the main loop of whatever runs (servo_step):
 *   (o & 7F) % 10 = 0  ENTER f
 *            1  HEADER f [l0 l1 l2 l3]: the image's length, or (f & 4) the one given
 *            2  END OF BATCH f: the all-zero header
 *            3  DATA f [n]: data block n: the next one (after the last ACKed), or
 *               (f & 4) n; its 1024 bytes are the image's page n - 1, the rest of the
 *               page filled with the image's pad byte; (f & 0x20) flips one byte of it;
 *               only the first MAX_RX_BLOCKS of an input go through the receiver
 *            4  EOF f
 *            5  IMAGE m v l0 l1 p x: the image to send: model (m % 4: own, another
 *               board's, m ^ own, own), version v, length IMAGE_MIN_BYTES + (l0 | l1 << 8)
 *               % (2 pages, or the whole slot if m & 0xE4 = 0xE4); pad byte p; if x & 1, byte
 *               x >> 1 of it (the info block too) is flipped after its CRC-32 was set
 *            6  BOOT: power cycle (the bootloader's install decision, then update mode)
 *            7  CUT k: the power goes at the (k & 31) + 1-th next program or erase (of
 *               the next power-up's install if k & 32), kind (k >> 6) % 3; the servo
 *               then boots again
 *            8  WAIT: 11 s of silence (the session times out)
 *            9  RAW f s b0 ... : a §10 frame of (s % 12) + 5 bytes, INS FF, sub FC or FE
 *               (f & 4), the rest from the input (LEN as it comes)
 *   f (every frame): bit 0 bad checksum, bit 1 one byte short (LEN says so), bit 3 wrong
 *   CRC-16, bit 4 block number complement wrong, bit 6 to another ID, bit 7 broadcast.
 * At most MAX_OPS operations.
 *
 * Invariants (abort on violation):
 *   1. never installs an image that fails its CRC-32 or names another model: whenever the
 *      bootloader starts the application, the application slot holds an image for this
 *      board whose CRC-32 (computed here, independently of src/crc.c) is right; and the
 *      application slot changes at power-up only when the staging slot held such an
 *      image;
 *   2. never writes outside the staging slot: the session never erases or programs the
 *      application slot or the store (the flash's per-page counts of erases and
 *      programs after every frame and at every power-up; the store's contents too);
 *   3. always answers: every update frame to the servo's own ID, damaged or not, gets an
 *      answer (straight to the session: exactly one), well-formed (D5 5D, own ID, LEN,
 *      ERR 0, checksum) with one byte C, ACK, NAK or CAN, or ACK then C; frames to another
 *      ID or broadcast get none (through the receiver, frames found inside a damaged one
 *      are answered after it, each well-formed).
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "boot.h"
#include "fuzz.h"
#include "hal_host.h"
#include "image.h"
#include "loader.h"
#include "proto.h"
#include "servo.h"
#include "update.h"

#define MAX_OPS 48u
/* Data blocks through the receiver per input, at most: 1,030 bytes each through the byte
 * loop cost five times what the session does with the block (the receiver is fuzz_frame's
 * and fuzz_bus's to attack); later ones go straight to the session. */
#define MAX_RX_BLOCKS 2u
/* IMAGE's m bits that ask for a length up to the whole slot (one image in sixteen): each
 * boot checks an installed image's CRC-32, so small images keep executions cheap. */
#define WHOLE_SLOT 0xE4u
#define SLOT_BYTES (HAL_SLOT_PAGES * HAL_FLASH_PAGE_BYTES)
#define FACTORY_BYTES 512u /* a small application: the bootloader checks it every boot */

const char fuzz_target_name[] = "fuzz_update";

static struct hal hal;
static struct servo servo;
static const struct board *board;
static uint8_t board_no; /* its index in board_all */
/* An image the host sends, padded to the slot (and flipped where the input says), with
 * the CRC-16s of its pages as they are needed. Two are kept, so neither is built twice
 * in a row: the one every input starts with, and the last other one. */
static struct sent_image {
    bool made;
    uint32_t len, flip;
    uint16_t model, seed;
    uint8_t version, pad;
    uint32_t crc_known; /* a bit per page */
    uint16_t crc[HAL_SLOT_PAGES];
    uint8_t bytes[SLOT_BYTES];
} images[2], *img = &images[0];
_Static_assert(HAL_SLOT_PAGES <= 32u, "a bit per page");
static uint8_t next_block;       /* after the last ACKed data block */
static uint8_t boot_cut, boot_cut_kind; /* a power cut planned for the next install */
static uint8_t app[SLOT_BYTES];  /* the application slot as of the last power-up */
static uint8_t store_pages[HAL_FLASH_PAGES][HAL_FLASH_PAGE_BYTES];
static uint32_t writes_outside[HAL_PAGE_STAGING];

/* A HAL copied without its transmit log (which is last, and large). */
#define HAL_FRESH_BYTES offsetof(struct hal, log)
_Static_assert(offsetof(struct hal, log) + sizeof hal.log == sizeof(struct hal),
               "the transmit log is the last member of struct hal");

/* CRC-32 (IEEE, reflected), four bytes a step through four tables ("slicing by 4"): not
 * the firmware's code. Start with 0xFFFFFFFF, finish with ~. */
FUZZ_NO_COVERAGE static uint32_t crc32_independent(uint32_t c, const uint8_t *p, uint32_t n)
{
    static uint32_t t[4][256];
    if (!t[0][1]) {
        for (uint32_t i = 0; i < 256u; i++) {
            uint32_t v = i;
            for (int k = 0; k < 8; k++)
                v = v & 1u ? 0xEDB88320u ^ (v >> 1) : v >> 1;
            t[0][i] = v;
        }
        for (uint32_t i = 0; i < 256u; i++)
            for (int k = 1; k < 4; k++)
                t[k][i] = (t[k - 1][i] >> 8) ^ t[0][t[k - 1][i] & 0xFFu];
    }
    for (; n >= 4u; n -= 4u, p += 4u) {
        c ^= (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
        c = t[3][c & 0xFFu] ^ t[2][(c >> 8) & 0xFFu] ^ t[1][(c >> 16) & 0xFFu] ^ t[0][c >> 24];
    }
    for (; n; n--)
        c = t[0][(c ^ *p++) & 0xFFu] ^ (c >> 8);
    return c;
}

/* CRC-16 (XMODEM: polynomial 0x1021, MSB first, start 0), table-driven: the block CRC the
 * host sends, not the firmware's code. */
FUZZ_NO_COVERAGE static uint16_t crc16_independent(const uint8_t *p, uint32_t n)
{
    static uint16_t table[256];
    if (!table[1])
        for (uint32_t i = 0; i < 256u; i++) {
            uint16_t t = (uint16_t)(i << 8);
            for (int k = 0; k < 8; k++)
                t = (uint16_t)((t & 0x8000u) ? (uint32_t)t << 1 ^ 0x1021u : (uint32_t)t << 1);
            table[i] = t;
        }
    uint16_t c = 0;
    for (uint32_t i = 0; i < n; i++)
        c = (uint16_t)(c << 8 ^ table[(c >> 8 ^ p[i]) & 0xFFu]);
    return c;
}

/* The 8-bit sum of a frame's bytes (its checksum), as the host computes it. */
FUZZ_NO_COVERAGE static uint8_t sum8_independent(const uint8_t *p, uint32_t n)
{
    uint32_t sum = 0;
    for (uint32_t i = 0; i < n; i++)
        sum += p[i];
    return (uint8_t)sum;
}

static uint32_t get32le(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put32le(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

/* CRC-32 of an image of len bytes (the crc field read as 0), page by page from
 * page(first + i), or from a buffer when mem is not 0. */
FUZZ_NO_COVERAGE static uint32_t image_crc32(uint8_t first_page, const uint8_t *mem, uint32_t len)
{
    static const uint8_t zero[4];
    const uint32_t at = IMAGE_INFO_OFFSET + IMAGE_OFF_CRC;
    uint32_t c = 0xFFFFFFFFu;
    for (uint32_t done = 0; done < len; done += HAL_FLASH_PAGE_BYTES) {
        uint8_t page = (uint8_t)(first_page + done / HAL_FLASH_PAGE_BYTES);
        const uint8_t *pg = mem ? &mem[done] : hal_flash_page(&hal, page);
        uint32_t n = len - done < HAL_FLASH_PAGE_BYTES ? len - done : HAL_FLASH_PAGE_BYTES;
        if (done == 0u) {
            c = crc32_independent(c, pg, at);
            c = crc32_independent(c, zero, 4);
            c = crc32_independent(c, &pg[at + 4u], n - at - 4u);
        } else {
            c = crc32_independent(c, pg, n);
        }
    }
    return ~c;
}

/* Slots are compared and copied whole (the flash's pages lie in one array) with a plain
 * loop: memcmp through ASan's interceptor checks both 26 KiB ranges' shadow first, and a
 * power-up compares three slots. */
FUZZ_NO_COVERAGE static bool same_bytes(const uint8_t *a, const uint8_t *b, uint32_t n)
{
    uint8_t diff = 0;
    for (uint32_t i = 0; i < n; i++)
        diff |= (uint8_t)(a[i] ^ b[i]);
    return diff == 0u;
}

FUZZ_NO_COVERAGE static void copy_slot(uint8_t *dst, uint8_t first_page)
{
    const uint8_t *src = hal_flash_page(&hal, first_page);
    for (uint32_t i = 0; i < SLOT_BYTES; i++)
        dst[i] = src[i];
}

static bool slot_equals(const uint8_t *src, uint8_t first_page)
{
    return same_bytes(src, hal_flash_page(&hal, first_page), SLOT_BYTES);
}

static bool slot_check(uint8_t first_page);

/* Writes (erases, programs) that reached the slot at first_page, ever. */
static uint32_t slot_writes(uint8_t first_page)
{
    uint32_t n = 0;
    for (uint8_t p = 0; p < HAL_SLOT_PAGES; p++)
        n += hal.flash.writes[first_page + p];
    return n;
}

/* Does the staging slot hold an image for this board with a right CRC-32? Kept until the
 * next write to the slot: most power-ups find it unchanged. input_no tells inputs apart
 * (each starts from a fresh flash, its write counts too). */
static uint32_t input_no;
static bool staging_good(void)
{
    static uint32_t seen_input, seen_writes;
    static bool seen_good, seen_any;
    uint32_t w = slot_writes(HAL_PAGE_STAGING);
    if (seen_any && seen_input == input_no && seen_writes == w)
        return seen_good;
    seen_good = slot_check(HAL_PAGE_STAGING);
    seen_any = true;
    seen_input = input_no;
    seen_writes = w;
    return seen_good;
}

/* Whether app[] (the application slot as of the last power-up) holds a good image:
 * -1 until computed. */
static int8_t app_good;

/* The start state the HAL came from last (0xFF: none yet), and whether the input since
 * changed app[]: the next input from the same start copies back only what changed. */
static uint8_t last_start = 0xFFu;
static bool app_dirty;

/* Does the slot at first_page hold an image for this board with a right CRC-32? */
static bool slot_check(uint8_t first_page)
{
    const uint8_t *info = &hal_flash_page(&hal, first_page)[IMAGE_INFO_OFFSET];
    uint32_t len = get32le(&info[IMAGE_OFF_LENGTH]);
    return get32le(&info[IMAGE_OFF_MAGIC]) == IMAGE_MAGIC && len >= IMAGE_MIN_BYTES &&
           len <= IMAGE_MAX_BYTES &&
           (info[IMAGE_OFF_MODEL] | info[IMAGE_OFF_MODEL + 1] << 8) == board->model_number &&
           image_crc32(first_page, 0, len) == get32le(&info[IMAGE_OFF_CRC]);
}

/* An image of the info block's layout (image.h), built here with the CRC-32 above. */
FUZZ_NO_COVERAGE static void image_build(uint8_t *p, uint32_t len, uint16_t model, uint8_t version,
                        uint32_t seed)
{
    uint32_t x = seed * 2654435761u + 0x9E3779B9u;
    for (uint32_t i = 0; i < len; i++) {
        if ((i & 3u) == 0u) {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
        }
        p[i] = (uint8_t)(x >> (8u * (i & 3u)));
    }
    uint8_t *info = &p[IMAGE_INFO_OFFSET];
    put32le(&info[IMAGE_OFF_MAGIC], IMAGE_MAGIC);
    put32le(&info[IMAGE_OFF_LENGTH], len);
    info[IMAGE_OFF_MODEL] = (uint8_t)model;
    info[IMAGE_OFF_MODEL + 1u] = (uint8_t)(model >> 8);
    info[IMAGE_OFF_VERSION] = version;
    info[IMAGE_OFF_VERSION + 1u] = 0;
    put32le(&info[IMAGE_OFF_CRC], image_crc32(0, p, len));
}

/* Invariant 2, cheaply: no erase or program of the store or the application slot since
 * the last power-up. */
static void check_writes(void)
{
    for (uint8_t p = 0; p < HAL_PAGE_STAGING; p++)
        FUZZ_CHECK(hal.flash.writes[p] == writes_outside[p]);
}

/* Power-up: the bootloader's decision (invariant 1), then update mode. */
static void boot(void)
{
    check_writes(); /* 2: the session left the store and the application alone */
    FUZZ_CHECK(same_bytes(&store_pages[0][0], hal_flash_page(&hal, 0), sizeof store_pages));

    hal.motor.last_us = hal.now_us; /* the plant does not move: update mode never drives it */
    hal_host_reboot(&hal);
    if (boot_cut) {
        hal.flash.cut_at = boot_cut;
        hal.flash.cut_kind = boot_cut_kind;
        boot_cut = 0;
    }
    bool staged_good = staging_good();
    uint32_t app_writes = slot_writes(HAL_PAGE_APP);
    servo_power_on(&servo, board, &hal); /* the bootloader, then the application or update mode */
    if (slot_writes(HAL_PAGE_APP) != app_writes && !slot_equals(app, HAL_PAGE_APP)) {
        FUZZ_CHECK(staged_good); /* 1: only a good staged image replaces the application */
        copy_slot(app, HAL_PAGE_APP);
        app_good = -1;
        app_dirty = true;
    }
    if (!loader_running(&servo.loader)) { /* the bootloader started the application */
        if (app_good < 0)
            app_good = slot_check(HAL_PAGE_APP);
        FUZZ_CHECK(app_good);
    }
    if (!hal.flash.powered) /* a cut during the install: power comes back */
        flash_sim_power_on(&hal.flash);
    memcpy(writes_outside, hal.flash.writes, sizeof writes_outside);
    next_block = 1;
}

/* Send one update frame (buf, len) as arriving now; check the answer (invariant 3). */
/* Deliver one update frame (buf, len) ending now: straight to loader_update_frame, or
 * (via_rx) byte by byte through the receiver to the main loop of what runs (servo_step:
 * the application's dispatcher, or update mode's loader_poll). Then its answer goes
 * out: invariant 3 on what was sent. */
static bool via_rx;

/* One main-loop pass of what runs. The plant is frozen: only update frames arrive, so
 * nothing ever drives the motor, and integrating it over a 1 s data block is costly. */
static void step(void)
{
    hal.motor.last_us = hal.now_us;
    servo_step(&servo);
}

/* A status packet sent from log entry from on: well-formed, from the servo's ID. Returns
 * its length; its bytes in b. */
static uint32_t check_sent(uint32_t from, uint8_t b[PROTO_STATUS_MAX])
{
    uint32_t n = hal.log_len - from;
    FUZZ_CHECK(n >= 6u && n <= PROTO_STATUS_MAX);
    for (uint32_t i = 0; i < n; i++)
        b[i] = hal_host_tx(&hal, from + i)->byte;
    FUZZ_CHECK(b[0] == PROTO_HEADER0 && b[1] == PROTO_HEADER1 && b[2] == servo.link.id);
    FUZZ_CHECK(b[3] == n - 4u);
    FUZZ_CHECK(proto_sum(&b[2], (uint16_t)(n - 3u)) == b[n - 1u]);
    return n;
}

static void deliver(const uint8_t *buf, uint16_t len, bool chk_ok)
{
    uint32_t baud = servo.link.baud;
    uint32_t byte_us = (10u * 1000000u + baud - 1u) / baud;
    uint32_t log_from = hal.log_len, sends = hal.sends;
    bool restart = false;
    if (via_rx) {
        static const uint8_t header[2] = {PROTO_HEADER0, PROTO_HEADER1};
        for (uint16_t i = 0; i < len + 2u; i++) {
            hal.now_us += byte_us;
            servo_rx_isr(&servo, i < 2u ? header[i] : buf[i - 2u]);
        }
        step();
    } else {
        hal.now_us += (uint32_t)len * byte_us;
        const struct frame f = {hal.now_us, len, chk_ok ? FRAME_OK : FRAME_BAD_CHECKSUM,
                                (uint8_t *)(uintptr_t)buf}; /* read only, as the receiver's */
        restart = loader_update_frame(&servo, &f) == UPDATE_RESTART;
    }
    check_writes();
    bool mine = buf[0] == servo.link.id;
    FUZZ_CHECK(servo.link.state == (mine ? LINK_WAITING : LINK_IDLE));
    uint8_t b[PROTO_STATUS_MAX];
    uint32_t n = 0;
    if (via_rx) {
        /* The main loop runs on at every event until all is quiet: the answer waits while
         * the receiver is inside a frame (a damaged frame's bytes may hold what looks
         * like the start of another), and frames found inside a damaged one come after
         * it, each answered in turn: every answer well-formed, the first is this one's. */
        for (unsigned pass = 0; pass < 16u && !hal.restart_requested; pass++) {
            uint32_t next = hal.now_us;
            uint32_t quiet = servo.rx.last_us + servo.rx.gap_us + servo.rx.byte_us + 1u;
            if (servo.link.state == LINK_SENDING)
                next = hal.tx_end_us;
            else if (servo.rx.in_frame) /* nothing starts before the receiver gives up */
                next = quiet;
            else if (servo.link.state == LINK_WAITING)
                next = servo.link.due_us;
            else if (servo.rx.rec_tail == servo.rx.rec_ready)
                break;
            if (servo.link.state == LINK_WAITING && (int32_t)(servo.link.due_us - next) > 0)
                next = servo.link.due_us;
            if ((int32_t)(next - hal.now_us) > 0)
                hal.now_us = next;
            uint32_t from = hal.log_len, before = hal.sends;
            uint8_t first = hal.sends == sends;
            step();
            if (hal.sends != before && first)
                n = check_sent(from, b);
            else if (hal.sends != before) {
                uint8_t other[PROTO_STATUS_MAX];
                (void)check_sent(from, other);
            }
        }
        FUZZ_CHECK(hal.restart_requested || servo.link.state == LINK_IDLE);
        restart = hal.restart_requested;
        if (!mine)
            return; /* (frames found inside it may have been answered) */
        FUZZ_CHECK(hal.sends >= sends + 1u);
    } else {
        if (!mine)
            return;
        hal.now_us = servo.link.due_us;
        (void)link_poll(&servo, hal.now_us, true);
        FUZZ_CHECK(hal.sends == sends + 1u);
        hal.now_us = hal.tx_end_us;
        FUZZ_CHECK(link_poll(&servo, hal.now_us, true));
        n = check_sent(log_from, b);
    }
    /* 3: the update answer: ERR 0, then C, ACK, NAK or CAN, or ACK C. */
    FUZZ_CHECK((n == 7u || n == 8u) && b[4] == 0u);
    if (n == 7u)
        FUZZ_CHECK(b[5] == UPDATE_READY || b[5] == UPDATE_ACK || b[5] == UPDATE_NAK ||
                   b[5] == UPDATE_CAN);
    else
        FUZZ_CHECK(b[5] == UPDATE_ACK && b[6] == UPDATE_READY);
    if (b[5] == UPDATE_ACK && buf[3] == PROTO_UPDATE_SUB_BLOCK && len > 5u &&
        buf[4] == PROTO_UPDATE_TYPE_DATA)
        next_block = (uint8_t)(buf[5] + 1u);
    if (b[5] == UPDATE_READY)
        next_block = 1;
    if (!hal.flash.powered || restart) /* a cut; a verified image */
        boot();
}

/* Frame around payload p[0..n) (INS FF, sub, ...), with the faults f asks for. */
static void send_frame(uint8_t f, const uint8_t *p, uint16_t n)
{
    static uint8_t buf[FRAME_BLOCK_BYTES + 2u];
    uint8_t id = servo.link.id;
    if (f & 0x40u)
        id = (uint8_t)(id + 1u) > PROTO_ID_MAX ? 0u : (uint8_t)(id + 1u);
    if (f & 0x80u)
        id = PROTO_ID_BROADCAST;
    if ((f & 2u) && n > 2u) /* the wrong length: the receiver cuts where LEN says */
        n = n > 253u ? 252u : (uint16_t)(n - 1u);
    buf[0] = id;
    uint16_t len = (uint16_t)(n + 3u); /* ID LEN payload CHK */
    buf[1] = n + 1u > 0xFFu ? 0xFFu : (uint8_t)(n + 1u); /* a data block says FF */
    memcpy(&buf[2], p, n);
    buf[len - 1u] = sum8_independent(buf, (uint16_t)(len - 1u));
    bool ok = true;
    if (f & 1u) {
        buf[len - 1u] ^= 0x5Au;
        ok = false;
    }
    if (!update_is_frame(buf, len))
        return; /* the dispatcher would not take it for one */
    deliver(buf, len, ok);
}

/* A header or data block: sub FE, type, number, its complement, data, CRC-16 (high
 * first). */
static void send_block(uint8_t f, uint8_t type, uint8_t num, const uint8_t *data, uint16_t n,
                       uint16_t crc)
{
    static uint8_t p[7u + PROTO_UPDATE_BLOCK_DATA];
    p[0] = 0xFFu;
    p[1] = PROTO_UPDATE_SUB_BLOCK;
    p[2] = type;
    p[3] = num;
    p[4] = (uint8_t)~num;
    if (f & 0x10u)
        p[4] ^= 0x01u;
    memcpy(&p[5], data, n);
    if (f & 8u)
        crc ^= 0x0101u;
    p[5u + n] = (uint8_t)(crc >> 8);
    p[6u + n] = (uint8_t)crc;
    send_frame(f, &p[0], (uint16_t)(n + 7u));
}

/* The CRC-16 of page pg of the image being sent, computed once per image. */
static uint16_t page_crc16(uint8_t pg)
{
    if (!((img->crc_known >> pg) & 1u)) {
        img->crc[pg] = crc16_independent(&img->bytes[pg * HAL_FLASH_PAGE_BYTES],
                                         HAL_FLASH_PAGE_BYTES);
        img->crc_known |= 1u << pg;
    }
    return img->crc[pg];
}

/* The image to send (IMAGE; every input starts with first set, operands all 0). */
static void make_image(struct fuzz_reader *r, bool first)
{
    uint8_t m = fuzz_get8(r), v = fuzz_get8(r);
    uint16_t l = fuzz_get8(r);
    l = (uint16_t)(l | fuzz_get8(r) << 8);
    uint8_t pad = fuzz_get8(r), x = fuzz_get8(r);
    uint16_t model = board->model_number;
    if ((m & 3u) == 1u)
        model = board_all[(board_no + 1u + (m >> 3) % (BOARD_COUNT - 1u)) % BOARD_COUNT]
                    ->model_number; /* another board's */
    else if ((m & 3u) == 2u)
        model = (uint16_t)(model ^ (m | 1u) << 4);
    uint32_t span = (m & WHOLE_SLOT) == WHOLE_SLOT ? IMAGE_MAX_BYTES - IMAGE_MIN_BYTES + 1u
                                                   : 2u * HAL_FLASH_PAGE_BYTES - IMAGE_MIN_BYTES + 1u;
    uint32_t len = IMAGE_MIN_BYTES + l % span;
    uint32_t flip = SLOT_BYTES; /* none */
    if (x & 1u)
        flip = (x >> 1) % 8u == 0u ? IMAGE_INFO_OFFSET + (x >> 4) % IMAGE_INFO_BYTES
                                   : (uint32_t)(x * 131u) % len;
    for (unsigned k = 0; k < 2u; k++) {
        struct sent_image *e = &images[k];
        if (e->made && e->len == len && e->flip == flip && e->model == model &&
            e->seed == l && e->version == v && e->pad == pad) {
            img = e;
            return;
        }
    }
    img = &images[first ? 0 : 1];
    image_build(img->bytes, len, model, v, l);
    memset(&img->bytes[len], pad, SLOT_BYTES - len);
    if (flip < SLOT_BYTES)
        img->bytes[flip] ^= 0x10u;
    img->made = true;
    img->len = len;
    img->flip = flip;
    img->model = model;
    img->seed = l;
    img->version = v;
    img->pad = pad;
    img->crc_known = 0;
}

/* hal := *from (a start state), the flash's pages only where the input wrote (its write
 * counts differ) unless the last input came from another start. */
static void start_restore(const struct hal *from, unsigned start_no)
{
    const size_t mem_at = offsetof(struct hal, flash) + offsetof(struct flash_sim, mem);
    const size_t mem_end = mem_at + sizeof hal.flash.mem;
    if (last_start != start_no) {
        memcpy(&hal, from, HAL_FRESH_BYTES);
        return;
    }
    for (uint8_t p = 0; p < FLASH_SIM_PAGES; p++)
        if (hal.flash.writes[p] != from->flash.writes[p])
            memcpy(hal.flash.mem[p], from->flash.mem[p], HAL_FLASH_PAGE_BYTES);
    memcpy(&hal, from, mem_at);
    memcpy((uint8_t *)&hal + mem_end, (const uint8_t *)from + mem_end, HAL_FRESH_BYTES - mem_end);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_progress();
    if (size < 1u)
        return 0;
    uint8_t bi = data[0] % BOARD_COUNT;
    unsigned start_no = bi * 2u + ((data[0] / BOARD_COUNT) & 1u);
    board = board_all[bi];
    board_no = bi;
    input_no++;
    boot_cut = 0;
    make_image(&(struct fuzz_reader){0, 0}, true);
    /* Every input starts from one of ten states (board, application erased or not) right
     * after its first power-up: made once each, then copied (a power-up costs more). */
    static struct {
        bool made;
        struct hal hal;
        struct servo servo;
        uint8_t app[SLOT_BYTES];
        uint8_t store[HAL_FLASH_PAGES][HAL_FLASH_PAGE_BYTES];
        uint32_t writes[HAL_PAGE_STAGING];
        int8_t app_good;
    } start[2u * BOARD_COUNT];
    _Static_assert(sizeof start / sizeof start[0] <= 0xFFu, "last_start: 0xFF is none");
    if (!start[start_no].made) {
        static uint8_t factory[FACTORY_BYTES];
        hal_host_init(&hal);
        image_build(factory, sizeof factory, board->model_number, 1, 7);
        hal_host_program_app(&hal, factory, sizeof factory);
        if (start_no & 1u) /* no valid application: update mode */
            for (uint8_t p = 0; p < HAL_SLOT_PAGES; p++)
                memset(hal.flash.mem[HAL_PAGE_APP + p], 0xFF, HAL_FLASH_PAGE_BYTES);
        hal.log_len = 0;
        copy_slot(app, HAL_PAGE_APP);
        app_good = -1;
        memcpy(store_pages, hal_flash_page(&hal, 0), sizeof store_pages);
        memcpy(writes_outside, hal.flash.writes, sizeof writes_outside);
        boot();
        FUZZ_CHECK(hal.log_len == 0u); /* (the copy below leaves the log out) */
        memcpy(&start[start_no].hal, &hal, HAL_FRESH_BYTES);
        start[start_no].servo = servo;
        memcpy(start[start_no].app, app, sizeof app);
        memcpy(start[start_no].store, store_pages, sizeof store_pages);
        memcpy(start[start_no].writes, writes_outside, sizeof writes_outside);
        start[start_no].app_good = app_good;
        start[start_no].made = true;
    } else {
        start_restore(&start[start_no].hal, start_no);
        servo = start[start_no].servo;
        if (app_dirty || last_start != start_no)
            memcpy(app, start[start_no].app, sizeof app);
        memcpy(store_pages, start[start_no].store, sizeof store_pages);
        memcpy(writes_outside, start[start_no].writes, sizeof writes_outside);
        app_good = start[start_no].app_good;
        next_block = 1;
    }
    last_start = (uint8_t)start_no;
    app_dirty = false;

    struct fuzz_reader r = {data + 1, size - 1u};
    unsigned rx_blocks = 0;
    for (unsigned n = 0; r.left && n < MAX_OPS; n++) {
        uint8_t o = fuzz_get8(&r), f;
        via_rx = (o & 0x80u) != 0u;
        static uint8_t d[PROTO_UPDATE_BLOCK_DATA];
        switch ((o & 0x7Fu) % 10u) {
        case 0: {
            const uint8_t p[2] = {0xFFu, PROTO_UPDATE_SUB_ENTER};
            send_frame(fuzz_get8(&r), p, 2);
            break;
        }
        case 1: {
            f = fuzz_get8(&r);
            uint32_t len = img->len;
            if (f & 4u)
                for (int i = 0; i < 4; i++) /* big-endian, as the header carries it */
                    len = i ? len << 8 | fuzz_get8(&r) : fuzz_get8(&r);
            memset(d, 0, PROTO_UPDATE_HEADER_DATA);
            d[0] = (uint8_t)(len >> 24);
            d[1] = (uint8_t)(len >> 16);
            d[2] = (uint8_t)(len >> 8);
            d[3] = (uint8_t)len;
            send_block(f, PROTO_UPDATE_TYPE_HEADER, 0, d, PROTO_UPDATE_HEADER_DATA,
                       crc16_independent(d, PROTO_UPDATE_HEADER_DATA));
            break;
        }
        case 2:
            memset(d, 0, PROTO_UPDATE_HEADER_DATA);
            send_block(fuzz_get8(&r), PROTO_UPDATE_TYPE_HEADER, 0, d, PROTO_UPDATE_HEADER_DATA,
                       crc16_independent(d, PROTO_UPDATE_HEADER_DATA));
            break;
        case 3: {
            f = fuzz_get8(&r);
            uint8_t num = (f & 4u) ? fuzz_get8(&r) : next_block;
            uint8_t pg = (uint8_t)((uint8_t)(num - 1u) % HAL_SLOT_PAGES);
            if (via_rx && ++rx_blocks > MAX_RX_BLOCKS)
                via_rx = false;
            memcpy(d, &img->bytes[pg * HAL_FLASH_PAGE_BYTES], PROTO_UPDATE_BLOCK_DATA);
            uint16_t crc;
            if (f & 0x20u) {
                d[(f * 37u) % PROTO_UPDATE_BLOCK_DATA] ^= 0x01u;
                crc = crc16_independent(d, PROTO_UPDATE_BLOCK_DATA);
            } else {
                crc = page_crc16(pg);
            }
            send_block(f, PROTO_UPDATE_TYPE_DATA, num, d, PROTO_UPDATE_BLOCK_DATA, crc);
            break;
        }
        case 4: {
            const uint8_t p[3] = {0xFFu, PROTO_UPDATE_SUB_BLOCK, PROTO_UPDATE_TYPE_EOF};
            send_frame(fuzz_get8(&r), p, 3);
            break;
        }
        case 5:
            make_image(&r, false);
            break;
        case 6:
            boot();
            break;
        case 7: {
            uint8_t k = fuzz_get8(&r);
            if (k & 32u) { /* in the bootloader's install, at the next power-up */
                boot_cut = (k & 31u) + 1u;
                boot_cut_kind = (uint8_t)((k >> 6) % 3u);
                break;
            }
            hal.flash.cut_at = hal.flash.ops + (k & 31u) + 1u;
            hal.flash.cut_kind = (uint8_t)((k >> 6) % 3u);
            break;
        }
        case 8:
            hal.now_us += UPDATE_TIMEOUT_US + 1000000u;
            break;
        default: {
            f = fuzz_get8(&r);
            uint8_t p[16];
            uint16_t k = (uint16_t)(fuzz_get8(&r) % 12u + 2u);
            p[0] = 0xFFu;
            p[1] = (f & 4u) ? PROTO_UPDATE_SUB_ENTER : PROTO_UPDATE_SUB_BLOCK;
            for (uint16_t i = 2; i < k; i++)
                p[i] = fuzz_get8(&r);
            send_frame(f, p, k);
            break;
        }
        }
    }
    boot();
    return 0;
}
