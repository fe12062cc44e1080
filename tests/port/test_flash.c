/* test_flash.c - hal/stm32f1/flash.c, both its builds, on the FPEC model (model_fpec.c):
 * the sequences RM0008 asks for, the faults a part can show (BSY stuck, an operation
 * already running, a 300 ms erase, PGERR, write protection, EOP late), a part of the
 * wrong size or page size, and then the store (records, compaction, power cuts) and a
 * whole firmware update (session, install, start) running through the real driver. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "image.h"
#include "port_app.h"
#include "regs.h"
#include "store.h"

#define STORE0 0x0800F000u
#define APP0 0x08002000u
#define STAGING0 0x08008800u
#define BOOTREC 0x08001C00u

static struct hal *const h = &hal_stm32;

/* Power-on of a fresh board with the application's clock set up (72 MHz). */
static void board_up(void)
{
    model_init();
    memset(h, 0, sizeof *h);
    port_image = PORT_APP;
    clock_init(h);
    assert_int_equal(h->clock_source, CLOCK_HSE_PLL);
}


static uint16_t half_at(uint32_t addr)
{
    const uint8_t *p = model_flash(addr);
    return (uint16_t)(p[0] | (p[1] << 8));
}

static bool locked(void)
{
    return (model.fpec.cr & FLASH_CR_LOCK) != 0u;
}

/* ---- The sequences --------------------------------------------------------------- */

static void pages_map_onto_the_linker_regions(void **state)
{
    (void)state;
    board_up();
    assert_ptr_equal(hal_flash_page(h, 0), model_flash(STORE0));
    assert_ptr_equal(hal_flash_page(h, HAL_FLASH_PAGES - 1u), model_flash(STORE0 + 3u * 1024u));
    assert_ptr_equal(hal_flash_page(h, HAL_PAGE_APP), model_flash(APP0));
    assert_ptr_equal(hal_flash_page(h, HAL_PAGE_STAGING), model_flash(STAGING0));
    assert_ptr_equal(hal_flash_page(h, HAL_PAGE_BOOTREC), model_flash(BOOTREC));
    assert_null(hal_flash_page(h, HAL_PAGE_BOOTREC + 1u));
    assert_null(hal_flash_page(h, HAL_PAGES_ALL + 5u));
}

static void erase_and_program_a_store_page(void **state)
{
    (void)state;
    board_up();
    for (uint16_t off = 0; off < 64u; off += 2u)
        assert_true(hal_flash_program(h, 1, off, (uint16_t)(0x1200u + off)));
    for (uint16_t off = 0; off < 64u; off += 2u)
        assert_int_equal(half_at(STORE0 + 1024u + off), 0x1200u + off);
    assert_true(locked());
    assert_true(hal_flash_erase(h, 1));
    for (uint32_t i = 0; i < 1024u; i++)
        assert_int_equal(model_flash(STORE0 + 1024u)[i], 0xFF);
    assert_true(locked()); /* locked again after every operation */
    assert_int_equal(model.fpec.erases, 1);
    assert_int_equal(model.fpec.programs, 32);
    assert_int_equal(h->flash_errors, 0);
    assert_false(model.fpec.key_locked);
    port_no_violation();
}

/* PGERR: a half-word that is not erased is not programmed, except with 0x0000. */
static void programming_a_written_half_word_fails(void **state)
{
    (void)state;
    board_up();
    assert_true(hal_flash_program(h, 0, 10, 0x1234));
    assert_false(hal_flash_program(h, 0, 10, 0x1030)); /* PGERR, skipped */
    assert_int_equal(half_at(STORE0 + 10u), 0x1234);
    assert_true(hal_flash_program(h, 0, 10, 0x0000)); /* the store's commit mark */
    assert_int_equal(half_at(STORE0 + 10u), 0x0000);
    assert_int_equal(h->flash_errors, 1);
    assert_true(hal_flash_program(h, 0, 12, 0xBEEF)); /* the error flag was cleared */
    assert_true(locked());
    port_no_violation();
}

static void odd_offsets_and_other_pages_are_refused(void **state)
{
    (void)state;
    board_up();
    assert_false(hal_flash_program(h, 0, 3, 0x1234));
    assert_false(hal_flash_program(h, 0, 1024, 0x1234));
    assert_false(hal_flash_erase(h, HAL_PAGE_BOOTREC + 1u));
    /* The application runs from its slot: only the bootloader installs into it. */
    assert_false(hal_flash_erase(h, HAL_PAGE_APP));
    assert_false(hal_flash_program(h, HAL_PAGE_APP + 3u, 0, 0));
    assert_int_equal(model.fpec.ops, 0);
    port_image = PORT_BOOT;
    assert_true(hal_flash_program(h, HAL_PAGE_APP + 3u, 0, 0x4321));
    assert_int_equal(half_at(APP0 + 3u * 1024u), 0x4321);
    assert_true(hal_flash_erase(h, HAL_PAGE_APP + 3u));
    port_no_violation();
}

/* WRPRTERR: a protected page is neither erased nor programmed, and the driver says so. */
static void write_protected_pages_fail(void **state)
{
    (void)state;
    board_up();
    assert_true(hal_flash_program(h, 2, 0, 0x5555));
    model.fpec.wrpr &= ~(1u << 15); /* 0x0800F000-0x0800FFFF: the store */
    assert_false(hal_flash_erase(h, 2));
    assert_false(hal_flash_program(h, 2, 2, 0x1111));
    assert_int_equal(half_at(STORE0 + 2048u), 0x5555);
    assert_int_equal(half_at(STORE0 + 2050u), 0xFFFF);
    assert_int_equal(h->flash_errors, 2);
    assert_true(hal_flash_erase(h, HAL_PAGE_STAGING)); /* elsewhere still works */
    assert_true(locked());
    port_no_violation();
}

/* ---- Faults ------------------------------------------------------------------------ */

static jmp_buf stopped;

/* An operation still running when the driver is called (left by a debugger, or by an
 * earlier one that outlived its wait): the driver waits for BSY before it touches the
 * FPEC, then does its own. */
static void waits_for_an_operation_already_running(void **state)
{
    (void)state;
    board_up();
    model_fpec_busy(MODEL_MS(5));
    uint64_t t0 = model.now;
    assert_true(hal_flash_program(h, 0, 0, 0xA5A5));
    assert_true(model.now - t0 >= MODEL_MS(5));
    assert_int_equal(half_at(STORE0), 0xA5A5);
    assert_true(locked());
    port_no_violation();
}

/* EOP shows one SR read after BSY falls (a fault injected, not RM0008's timing): the
 * verdict comes from SR read again after the wait, so a good write is not failed. */
static void success_is_read_afresh_after_bsy_falls(void **state)
{
    (void)state;
    board_up();
    model.fpec.flag_lag = 1;
    assert_true(hal_flash_program(h, 0, 4, 0x0102));
    assert_true(hal_flash_erase(h, 3));
    assert_int_equal(h->flash_errors, 0);
    port_no_violation();
}

/* BSY stuck: the wait ends (bounded), the operation fails, and the driver never writes
 * the busy FPEC (no relock, no PG/PER cleared under it), nor reads the array (the CPU
 * would stall for ever). Once BSY falls the next operation works. The watchdog, fed
 * while waiting, does not reset the chip. */
static void a_stuck_bsy_is_waited_out_and_never_touched(void **state)
{
    (void)state;
    board_up();
    hal_watchdog_start(h);
    model.fpec.stuck = true;
    if (model_catch(stopped))
        fail_msg("the chip reset while BSY was stuck");
    uint64_t t0 = model.now;
    assert_false(hal_flash_program(h, 0, 0, 0x1111));
    uint64_t waited = model.now - t0;
    assert_true(waited >= MODEL_MS(400)); /* long enough for any erase */
    assert_true(waited <= MODEL_MS(1500)); /* and bounded */
    assert_false(hal_flash_erase(h, 1)); /* still busy: waits again, starts nothing */
    assert_int_equal(model.fpec.ops, 1);
    port_no_violation();
    /* BSY falls at last: the program completes, and the next operation runs. */
    model.fpec.stuck = false;
    model.fpec.op_end = model.now + MODEL_MS(1);
    assert_true(hal_flash_erase(h, 1));
    assert_true(locked());
    assert_int_equal(h->flash_errors, 2);
    port_no_violation();
}

/* An erase of 300 ms (a part slower than the STM32F103's 40 ms): waited for, the
 * watchdog (167 ms at the LSI's fastest) fed all along, the page erased. */
static void a_300_ms_erase_completes_without_a_watchdog_reset(void **state)
{
    (void)state;
    board_up();
    model.iwdg.lsi_hz = 60000; /* the shortest timeout: 167 ms */
    hal_watchdog_start(h);
    assert_true(hal_flash_program(h, 2, 0, 0x0000));
    model.fpec.erase_ticks = MODEL_MS(300);
    if (model_catch(stopped))
        fail_msg("the watchdog reset the chip during a 300 ms erase");
    uint64_t t0 = model.now;
    assert_true(hal_flash_erase(h, 2));
    assert_true(model.now - t0 >= MODEL_MS(300));
    assert_int_equal(half_at(STORE0 + 2048u), 0xFFFF);
    assert_true(model.iwdg.feeds > 0);
    port_no_violation();
}

/* ---- The part ------------------------------------------------------------------------ */

/* The build's map is for 64 KiB in 1 KiB pages (STM32F103x8; the xB's 128 KiB has the
 * same pages). A part with 2 KiB pages would erase a neighbour with every page; a
 * smaller one has no store at 0x0800F000. Flash writes are refused on both. */
static void a_part_of_another_flash_size_is_never_written(void **state)
{
    (void)state;
    static const uint32_t kib[] = {16, 32, 256, 512};
    for (size_t i = 0; i < sizeof kib / sizeof kib[0]; i++) {
        board_up();
        port_image = PORT_BOOT;
        model.fpec.flash_kib = kib[i];
        model.fpec.page_bytes = kib[i] > 128u ? 2048u : 1024u;
        memset(model.fpec.mem + (STORE0 - MODEL_FLASH_BASE), 0x5A, 1024); /* page 0 */
        assert_false(hal_flash_erase(h, 1));   /* page 0's neighbour on a 2 KiB part */
        assert_false(hal_flash_program(h, 1, 0, 0x1234));
        assert_false(hal_flash_erase(h, HAL_PAGE_BOOTREC));
        assert_false(hal_flash_program(h, HAL_PAGE_APP, 0, 0));
        assert_int_equal(model.fpec.ops, 0);
        assert_int_equal(model_flash(STORE0)[0], 0x5A);
        port_no_violation();
    }
    board_up();
    model.fpec.flash_kib = 128; /* STM32F103xB: the same 1 KiB pages */
    assert_true(hal_flash_erase(h, 1));
    assert_true(hal_flash_program(h, 1, 0, 0x1234));
    port_no_violation();
}

/* ---- The store through the driver ----------------------------------------------------- */

static struct regs r;
static struct store st;

/* Power-on (the reset clock: the store's boot runs before the clock is set up), then the
 * store read into the factory table. No commit budget: every write commits. */
static void store_boot(void)
{
    model_reset(MODEL_RESET_POWER);
    memset(h, 0, sizeof *h);
    port_image = PORT_APP;
    regs_init(&r, &board_foot);
    store_load(&st, h, &r, 0);
    st.refill_us = 0;
}

/* The host's i-th write: one register, or both angle limits in one group. */
static void store_step(uint32_t i)
{
    switch (i % 4u) {
    case 0:
        regs_set(&r, REG_ID, (uint8_t)(1u + i % 200u));
        break;
    case 1:
        regs_set(&r, REG_RETURN_DELAY, (uint8_t)(i % 251u));
        break;
    case 2: /* CW <= CCW must hold after any cut */
        regs_set(&r, REG_CW_LIMIT, (uint16_t)(i % 100u));
        regs_set(&r, REG_CCW_LIMIT, (uint16_t)(100u + i % 300u));
        break;
    default:
        regs_set(&r, REG_TEMPERATURE_LIMIT, (uint8_t)(60u + i % 40u));
        regs_set(&r, REG_UNLOAD_CONDITIONS, (uint8_t)(i % 128u));
        break;
    }
    (void)regs_take_ee_changed(&r);
    store_sync(&st, &r, 0);
    store_poll(&st, &r, 0, true); /* the idle-time pre-erase */
}

static bool ee_equal(const uint8_t *a, const uint8_t *b)
{
    for (uint8_t x = 0; x < REGS_SIZE; x++)
        if (regs_table[x].area == REG_AREA_EE && a[x] != b[x])
            return false;
    return true;
}

static uint8_t snap_flash[MODEL_FLASH_BYTES];
static struct regs snap_r;
static struct store snap_st;

static void snap_save(void)
{
    memcpy(snap_flash, model.fpec.mem, sizeof snap_flash);
    snap_r = r;
    snap_st = st;
}

static void snap_restore(void)
{
    memcpy(model.fpec.mem, snap_flash, sizeof snap_flash);
    r = snap_r;
    st = snap_st;
}

/* Run fn(arg) with a power cut due: true once it struck (the code stopped there). Its own
 * function, so no caller's local lives across the setjmp. */
static bool cut_during(void (*fn)(uint32_t), uint32_t arg)
{
    if (model_catch(stopped))
        return true;
    fn(arg);
    model.exit = NULL;
    return false;
}

#define STORE_STEPS 240u /* about one and a half pages of writes: two compactions */

/* The store of docs/persistence.md on the real driver: a power cut at every erase and
 * program of every write (clean, just after it, torn), across compactions and the
 * pre-erase; after each, the power-on store holds the whole old image or the whole new
 * one, and takes the next write. */
static void the_store_survives_a_cut_at_every_operation(void **state)
{
    (void)state;
    board_up();
    model.fpec.program_ticks = MODEL_US(5); /* fast: their timing has its own tests */
    model.fpec.erase_ticks = MODEL_US(300);
    store_boot();
    uint32_t trials = 0, seq0 = st.seq;
    for (uint32_t i = 0; i < STORE_STEPS; i++) {
        snap_save();
        uint8_t before[REGS_SIZE], after[REGS_SIZE];
        memcpy(before, r.mem, sizeof before);
        model.fpec.ops = 0;
        store_step(i);
        uint32_t ops = model.fpec.ops;
        memcpy(after, r.mem, sizeof after);
        for (uint32_t n = 1; n <= ops; n++) {
            for (uint8_t kind = MODEL_CUT_CLEAN; kind <= MODEL_CUT_TORN; kind++) {
                snap_restore();
                model.fpec.ops = 0;
                model.fpec.cut_at = n;
                model.fpec.cut_kind = kind;
                model.fpec.rng = 0x9E3779B9u * (i * 7919u + n * 31u + kind + 1u);
                if (!cut_during(store_step, i))
                    fail_msg("step %u: no power cut at operation %u of %u", i, n, ops);
                model.fpec.cut_at = 0;
                store_boot();
                if (!ee_equal(r.mem, before) && !ee_equal(r.mem, after))
                    fail_msg("step %u, cut at %u (kind %u): neither the old image nor the "
                             "new one", i, n, kind);
                assert_true(regs_get(&r, REG_CW_LIMIT) <= regs_get(&r, REG_CCW_LIMIT));
                store_step(i); /* the write again, in full: it lands */
                memcpy(after, r.mem, sizeof after);
                store_boot();
                assert_true(ee_equal(r.mem, after));
                trials++;
            }
        }
        snap_restore();
        store_step(i);
    }
    assert_true(st.seq >= seq0 + 2u); /* compactions happened */
    uint8_t last[REGS_SIZE];
    memcpy(last, r.mem, sizeof last);
    store_boot();
    assert_true(ee_equal(r.mem, last));
    assert_int_equal(st.faults, 0);
    print_message("%u power cuts through flash.c on the FPEC model\n", trials);
    port_no_violation();
}

/* ---- A whole update through the driver ------------------------------------------------ */

#define UPDATE_BYTES 6000u
static uint8_t image_v1[UPDATE_BYTES], image_v2[UPDATE_BYTES];

/* The host sends a frame at baud and reads the answer's data (after ERR): its length. */
static uint32_t host_ask(const uint8_t *f, uint32_t n, uint32_t baud, uint8_t *data)
{
    uint32_t from = model.usart.tx_len;
    port_host_send(f, n, baud);
    uint8_t ans[16] = {0};
    if (port_await(from, 4, ans, MODEL_MS(200)) || model.usart.tx_len < from + 4u)
        fail_msg("no answer");
    uint32_t len = ans[3];
    if (port_await(from, 4u + len, ans, MODEL_MS(50)))
        fail_msg("reset during an answer");
    assert_int_equal(ans[2], 1);    /* ID */
    assert_int_equal(ans[4], 0x00); /* ERR */
    memcpy(data, &ans[5], len - 2u);
    return len - 2u;
}

static const uint8_t ACK[] = {UPDATE_ACK}, ACK_C[] = {UPDATE_ACK, UPDATE_READY},
                     READY[] = {UPDATE_READY};

static void host_ask_expect(const uint8_t *f, uint32_t n, uint32_t baud, const uint8_t *want,
                            uint32_t wn)
{
    uint8_t data[8];
    assert_int_equal(host_ask(f, n, baud, data), wn);
    if (wn)
        assert_memory_equal(data, want, wn);
}

/* PROTOCOL.md §10 over USART1 at 921600 baud into the running application, every block
 * erased, programmed and read back through flash.c on the FPEC model; the restart; the
 * bootloader's build of flash.c installing it; the new image running, confirmed. */
static void a_whole_update_runs_through_the_driver(void **state)
{
    (void)state;
    port_board_new(true, true);
    port_image_build(image_v1, UPDATE_BYTES, BOARD_MODEL_ARM, 1, 11);
    port_image_build(image_v2, UPDATE_BYTES, BOARD_MODEL_ARM, 2, 22);
    memcpy(model.fpec.mem + (APP0 - MODEL_FLASH_BASE), image_v1, UPDATE_BYTES); /* factory */
    assert_true(port_bootloader());
    port_application();
    assert_int_equal(port_servo.regs.mem[REG_FIRMWARE_VERSION], 1);
    static uint8_t f[PROTO_UPDATE_DATA_FRAME + 8u];
    /* 921600 baud first (code 8). */
    const uint8_t baud8[] = {REG_BAUD_RATE, 8};
    host_ask_expect(f, port_frame(f, 1, INS_WRITE, baud8, 2), 9600, NULL, 0);
    assert_int_equal(port_loop_for(MODEL_MS(5)), 0);
    const uint32_t baud = 921600u;
    host_ask_expect(f, enter_frame(f, 1), baud, READY, 1);
    host_ask_expect(f, header_frame(f, 1, UPDATE_BYTES), baud, ACK_C, 2);
    uint32_t blocks = (UPDATE_BYTES + 1023u) / 1024u;
    for (uint32_t b = 0; b < blocks; b++) {
        uint8_t data[1024];
        memset(data, 0x1A, sizeof data); /* YMODEM's padding */
        uint32_t n = UPDATE_BYTES - b * 1024u < 1024u ? UPDATE_BYTES - b * 1024u : 1024u;
        memcpy(data, &image_v2[b * 1024u], n);
        uint16_t len = block_frame(f, 1, PROTO_UPDATE_TYPE_DATA, (uint8_t)(b + 1u), data);
        host_ask_expect(f, len, baud, ACK, 1);
    }
    assert_int_equal(memcmp(model_flash(STAGING0), image_v2, UPDATE_BYTES), 0);
    host_ask_expect(f, eof_frame(f, 1), baud, ACK_C, 2);
    uint8_t zero[PROTO_UPDATE_HEADER_DATA] = {0};
    uint32_t from = model.usart.tx_len;
    port_host_send(f, block_frame(f, 1, PROTO_UPDATE_TYPE_HEADER, 0, zero), baud);
    uint8_t ans[8];
    /* The ACK leaves, then the servo restarts (hal_restart: SYSRESETREQ). */
    assert_int_equal(port_await(from, 7, ans, MODEL_MS(200)), MODEL_EXIT_RESET);
    assert_int_equal(model.usart.tx_len, from + 7u);
    assert_int_equal(ans[5], UPDATE_ACK);
    assert_true(model.rcc.csr & (1u << 28)); /* SFTRSTF */
    assert_int_equal(h->flash_errors, 0);
    /* The bootloader installs it through its own flash.c and starts it. */
    uint32_t erases = model.fpec.erases;
    assert_true(port_bootloader());
    assert_int_equal(memcmp(model_flash(APP0), image_v2, UPDATE_BYTES), 0);
    assert_true(model.fpec.erases - erases >= blocks + 2u); /* the slot, record, staging */
    assert_int_equal(model_flash(STAGING0)[0], 0xFF);        /* the staged copy consumed */
    port_application();
    assert_int_equal(port_servo.regs.mem[REG_FIRMWARE_VERSION], 2);
    /* It answers, at the stored baud (an update keeps the store), and confirms. */
    uint8_t data[8];
    const uint8_t read2[] = {REG_FIRMWARE_VERSION, 1};
    assert_int_equal(host_ask(f, port_frame(f, 1, INS_READ, read2, 2), baud, data), 1);
    assert_int_equal(data[0], 2);
    assert_int_equal(port_loop_for(MODEL_MS(5)), 0);
    uint16_t end;
    assert_int_equal(boot_unconfirmed(h, &end), 0);
    assert_int_equal(end, 4); /* START, CONFIRM */
    assert_int_equal(h->flash_errors, 0);
    port_no_violation();
}

static void bootloader_once(uint32_t unused)
{
    (void)unused;
    (void)port_bootloader();
}

/* The operation numbers of the erases (FLASH_CR written with STRT: the next op). */
static uint32_t erase_op[32], erase_ops;

static void note_erase(uintptr_t addr, bool write)
{
    if (write && addr == 0x40022010u && (model.fpec.cr & FLASH_CR_PER) && erase_ops < 32u)
        erase_op[erase_ops++] = model.fpec.ops + 1u;
}

/* A power cut anywhere in an install (the bootloader's flash.c copying the staged image
 * over the application): the next power-on installs it again and starts it, whatever
 * the cut left (clean, done, torn). Every erase, every 19th program, and the last ones
 * (consuming the staged copy, the START mark), each kind; the operations are made fast
 * (their timing has its own tests). */
static void a_cut_install_completes_at_the_next_power_on(void **state)
{
    (void)state;
    static uint8_t staged[2500], old[2500];
    port_board_new(true, true);
    model.fpec.program_ticks = MODEL_US(5);
    model.fpec.erase_ticks = MODEL_US(300);
    port_image_build(old, sizeof old, BOARD_MODEL_ARM, 1, 5);
    port_image_build(staged, sizeof staged, BOARD_MODEL_ARM, 3, 6);
    memcpy(model.fpec.mem + (APP0 - MODEL_FLASH_BASE), old, sizeof old);
    memcpy(model.fpec.mem + (STAGING0 - MODEL_FLASH_BASE), staged, sizeof staged);
    model.fpec.mem[STAGING0 - MODEL_FLASH_BASE + 25u * 1024u + IMAGE_MARK_OFFSET] = 0;
    model.fpec.mem[STAGING0 - MODEL_FLASH_BASE + 25u * 1024u + IMAGE_MARK_OFFSET + 1u] = 0;
    snap_save();
    model.fpec.ops = 0;
    model.on_access = note_erase;
    erase_ops = 0;
    assert_true(port_bootloader());
    model.on_access = NULL;
    uint32_t ops = model.fpec.ops, trials = 0;
    assert_true(erase_ops >= 5u); /* three pages, the record, the staged copy */
    assert_int_equal(memcmp(model_flash(APP0), staged, sizeof staged), 0);
    for (uint32_t n = 1; n <= ops; n++) {
        bool erase = false;
        for (uint32_t e = 0; e < erase_ops; e++)
            erase = erase || erase_op[e] == n;
        if (n % 19u != 0u && n + 4u < ops && !erase)
            continue;
        for (uint8_t kind = MODEL_CUT_CLEAN; kind <= MODEL_CUT_TORN; kind++) {
            snap_restore();
            model_reset(MODEL_RESET_POWER);
            model.fpec.cut_at = n;
            model.fpec.cut_kind = kind;
            if (!cut_during(bootloader_once, 0))
                fail_msg("no cut at operation %u of %u", n, ops);
            model.fpec.cut_at = 0;
            model_reset(MODEL_RESET_POWER);
            model.exit = NULL;
            assert_true(port_bootloader());
            if (memcmp(model_flash(APP0), staged, sizeof staged) != 0)
                fail_msg("cut at operation %u of %u (kind %u): not installed", n, ops, kind);
            trials++;
        }
    }
    print_message("%u cuts in an install of %u operations\n", trials, ops);
    port_no_violation();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(pages_map_onto_the_linker_regions),
        cmocka_unit_test(erase_and_program_a_store_page),
        cmocka_unit_test(programming_a_written_half_word_fails),
        cmocka_unit_test(odd_offsets_and_other_pages_are_refused),
        cmocka_unit_test(write_protected_pages_fail),
        cmocka_unit_test(waits_for_an_operation_already_running),
        cmocka_unit_test(success_is_read_afresh_after_bsy_falls),
        cmocka_unit_test(a_stuck_bsy_is_waited_out_and_never_touched),
        cmocka_unit_test(a_300_ms_erase_completes_without_a_watchdog_reset),
        cmocka_unit_test(a_part_of_another_flash_size_is_never_written),
        cmocka_unit_test(the_store_survives_a_cut_at_every_operation),
        cmocka_unit_test(a_whole_update_runs_through_the_driver),
        cmocka_unit_test(a_cut_install_completes_at_the_next_power_on),
    };
    if (getenv("PORT_TEST"))
        cmocka_set_test_filter(getenv("PORT_TEST"));
    return cmocka_run_group_tests(tests, NULL, NULL);
}
