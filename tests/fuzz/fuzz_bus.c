/* fuzz_bus.c - a whole host-built servo (receiver, dispatcher, control table, motion,
 * safety, the store on simulated flash) fed an arbitrary byte stream with arbitrary
 * timing, checking invariants after every byte, gap and dispatched frame.
 *
 * Built two ways from this one source (fuzz.h): the libFuzzer target of `make fuzz`, and
 * the replay driver fuzz_replay_bus that CTest runs over tests/fuzz/corpus/fuzz_bus/ and
 * tests/fuzz/findings/fuzz_bus/. It plays up to 6 s of bus time per input (MAX_VIRTUAL_US;
 * about 100 inputs per second); the fast targets (fuzz_frame, fuzz_store, fuzz_update,
 * fuzz_planner) cover the same surfaces without the real-time part.
 *
 * Input: byte 0 picks the board (byte 0 % BOARD_COUNT, in board_all's order) and the
 * faults the servo's sensors see (byte 0 / BOARD_COUNT, bits: 0-1 supply low, high or
 * dropping low then high; 2 over-temperature (90 C); 3 a current spike; 4 the shaft jammed; 5 a
 * cold sensor (-30 C), with bit 2 one past the register's range (150 C)), present in
 * every other half second of virtual time from the second one on; byte 1 the servo's ID
 * (0: factory ID 1). The rest is the wire, from the host:
 *   FF FF      one data byte FF
 *   FF FE      power cycle (reboot the servo; the flash survives)
 *   FF FD k    plan a flash power cut at the (k & 15) + 1-th next program or erase, kind
 *              (k >> 4) % 3 (clean, done, torn); the servo reboots when it happens
 *   FF g       (g <= FC) idle line for (g + 1)^2 x 10 us (10 us ... 0.64 s)
 *   other b    one data byte, 10 bit-times at the servo's baud rate
 * The main loop runs every POLL_US of virtual time; input past MAX_VIRTUAL_US is ignored.
 *
 * The servo powers up as on the MCU (servo_power_on: factory image in the application
 * slot, the bootloader's decision), and a restart it asks for (the end of a firmware
 * update, hal_restart) is a power cycle.
 *
 * Invariants (abort on violation, so libFuzzer keeps the input):
 *   1. the identity registers (read-only, EEPROM: model number, firmware version) never
 *      change while the image runs (an update changes the version only across a
 *      restart); every writable register is within its descriptor's range; CW <= CCW
 *      (while the application runs: three power cycles in a row before it confirms
 *      its start leave the servo in update mode, docs/update.md, which has no table;
 *      nor has an image that hangs at start, which a seed installs);
 *   2. no answer is scheduled for a broadcast frame other than PING and the identity
 *      sub-command (include/ident.h: answered at ID 0xFF);
 *   3. from power-up the motor stays off (bridge disabled, duty 0) until a frame with a
 *      good checksum other than PING or READ has been dispatched;
 *   4. after a WRITE of moving speed 0 (bits 0-14) that the servo accepted, the drive
 *      stays at 0 until the next frame with a good checksum is dispatched;
 *   5. interrupts are never left masked by the main loop. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../identity_check.h"
#include "fuzz.h"
#include "hal_host.h"
#include "ident.h"
#include "proto.h"
#include "servo.h"

#define POLL_US 250u
#define MAX_VIRTUAL_US 6000000u /* an input plays at most 6 s of bus time (a homing) */

const char fuzz_target_name[] = "fuzz_bus";

static struct hal hal;
static struct servo servo;
static uint8_t factory[REGS_SIZE];
static uint8_t faults;        /* byte 0 / 5 */
static bool motion_commanded; /* invariant 3 */
static bool speed0_window;    /* invariant 4 */

#define CHECK(cond)                                                                         \
    do {                                                                                    \
        if (!(cond)) {                                                                      \
            fprintf(stderr, "fuzz_bus: invariant failed at %s:%d: %s (t = %u us)\n",        \
                    __FILE__, __LINE__, #cond, (unsigned)hal.now_us);                       \
            abort();                                                                        \
        }                                                                                   \
    } while (0)

static uint8_t checked[REGS_SIZE]; /* the table as last checked */

/* Checks the table whenever it differs from the one last checked. */
static void check_table(void)
{
    const struct servo *s = &servo;
    if (memcmp(checked, s->regs.mem, sizeof checked) == 0)
        return;
    memcpy(checked, s->regs.mem, sizeof checked);
    if (loader_running(&s->loader) || s->hal->image_hung)
        return; /* no application runs: update mode (loader.h) keeps ID, baud and delay
                 * only; an image that hangs (the host model) keeps nothing */
    CHECK(identity_unchanged(s, factory));
    CHECK(regs_first_invalid(&s->regs) == REGS_SIZE);
}

static void check_all(void)
{
    check_table();
    CHECK(hal.irq_depth == 0);
    if (!motion_commanded) {
        CHECK(!hal.motor.enabled);
        CHECK(hal.motor.duty == 0);
    }
    if (speed0_window)
        CHECK(hal.motor.duty == 0);
}

static void power_up(void)
{
    hal_host_reboot(&hal);
    servo_power_on(&servo, servo.board, &hal);
    factory[REG_FIRMWARE_VERSION] = servo.regs.mem[REG_FIRMWARE_VERSION]; /* an installed update's */
    motion_commanded = false;
    speed0_window = false;
}

/* A WRITE that sets the moving speed to 0 (bits 0-14) without switching the brake on. */
static bool writes_speed0(const uint8_t *buf, uint16_t len)
{
    if (buf[2] != INS_WRITE || len < 6u)
        return false;
    uint8_t addr = buf[3];
    uint16_t n = (uint16_t)(len - 5u); /* ID LEN INS ADDR data... CHK */
    if (addr > REG_MOVING_SPEED || addr + n < REG_MOVING_SPEED + 2u)
        return false;
    if (addr <= REG_BRAKE && addr + n > REG_BRAKE && buf[4 + REG_BRAKE - addr])
        return false;
    const uint8_t *p = &buf[4 + REG_MOVING_SPEED - addr];
    return (p[0] | ((p[1] & 0x7Fu) << 8)) == 0u;
}

/* One main-loop pass, watching which frame it dispatches. The frame may have become
 * ready inside servo_poll() (the receiver's time-out releases frames held behind a broken
 * one), so it is looked up afterwards: the one the pass peeked (the receiver's view),
 * its bytes untouched by the receive interrupt, which cannot run during the pass here. */
static void poll_once(void)
{
    uint8_t tail = servo.rx.rec_tail;
    uint8_t my_id = servo.link.id;
    servo_step(&servo);
    if (servo.rx.rec_tail != tail) { /* dispatched */
        const struct frame *f = &servo.rx.view;
        const uint8_t *buf = f->buf;
        uint16_t len = f->len;
        bool ok = f->status == FRAME_OK;
        /* The identity sub-command (include/ident.h) answers broadcasts, at ID 0xFF. */
        bool ident = ok && buf[2] == INS_CUSTOM && buf[1] > 3u && buf[3] == IDENT_SUB;
        if (buf[0] == PROTO_ID_BROADCAST && !(ok && buf[2] == INS_PING) && !ident)
            CHECK(servo.link.state == LINK_IDLE); /* invariant 2 */
        if (ok) {
            speed0_window = false;
            if (buf[2] != INS_PING && buf[2] != INS_READ)
                motion_commanded = true;
            if ((buf[0] == my_id || buf[0] == PROTO_ID_BROADCAST) &&
                writes_speed0(buf, len) &&
                (regs_get(&servo.regs, REG_MOVING_SPEED) & 0x7FFFu) == 0u)
                speed0_window = true;
        }
    }
    if (!hal.flash.powered || hal.restart_requested) /* a planned cut, or a restart */
        power_up();
    check_all();
}

/* The sensors as the faults of the input have them now. */
static void sense(void)
{
    bool on = ((hal.now_us / 500000u) & 1u) != 0u;
    static const uint16_t supply[4] = {12000u, 8000u, 16000u, 8000u};
    uint8_t v = faults & 3u;
    if (v == 3u && (hal.now_us / 1000000u) & 1u)
        v = 2u; /* dropping low, then high */
    hal.supply_mv = on ? supply[v] : 12000u;
    static const int16_t temperature_dc[4] = {250, 900, -300, 1500};
    hal.temperature_dc = on ? temperature_dc[((faults >> 2) & 1u) | ((faults >> 4) & 2u)] : 250;
    hal.current_extra_ma = on && (faults & 8u) ? 5000u : 0u;
    hal.motor.blocked = on && (faults & 16u);
}

/* Advance virtual time to t, running the main loop every POLL_US. */
static void run_until(uint32_t t)
{
    while ((int32_t)(t - hal.now_us) > 0) {
        uint32_t step = t - hal.now_us;
        hal.now_us += step < POLL_US ? step : POLL_US;
        if (faults)
            sense();
        poll_once();
    }
}

static void send_byte(uint8_t b)
{
    uint32_t baud = hal.baud ? hal.baud : 9600u;
    run_until(hal.now_us + (10u * 1000000u + baud - 1u) / baud); /* the byte's 10 bits */
    servo_rx_isr(&servo, b);
    poll_once();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_progress();
    if (size < 2u)
        return 0;
    const struct board *b = board_all[data[0] % BOARD_COUNT];
    faults = (uint8_t)(data[0] / BOARD_COUNT);
    hal_host_init(&hal);
    hal_host_attach_board(&hal, b);
    hal_host_program_factory(&hal, b);
    servo_power_on(&servo, b, &hal);
    if (data[1]) {
        servo.regs.mem[REG_ID] = data[1] < PROTO_ID_BROADCAST ? data[1] : 1u;
        link_latch(&servo);
    }
    memcpy(factory, servo.regs.mem, sizeof factory);
    memset(checked, 0, sizeof checked);
    checked[0] = (uint8_t)~factory[0]; /* differs: the first check runs */
    motion_commanded = false;
    speed0_window = false;
    check_all();

    struct fuzz_reader r = {data + 2, size - 2u};
    for (struct fuzz_wire_event e; hal.now_us < MAX_VIRTUAL_US &&
                                   (e = fuzz_wire_next(&r)).kind != FUZZ_WIRE_END;) {
        switch (e.kind) {
        case FUZZ_WIRE_BYTE:
            send_byte(e.byte);
            break;
        case FUZZ_WIRE_POWER_CYCLE:
            power_up();
            check_all();
            break;
        case FUZZ_WIRE_CUT:
            hal.flash.cut_at = hal.flash.ops + e.cut_after;
            hal.flash.cut_kind = e.cut_kind;
            break;
        default: /* FUZZ_WIRE_IDLE */
            run_until(hal.now_us + e.idle_us);
            break;
        }
    }
    run_until(hal.now_us + 20000u); /* let the last answer go out */
    return 0;
}
