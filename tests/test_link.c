/* test_link.c - the servo's side of the bus (PROTOCOL.md §1, §3.2, §4.1, §5.2): baud
 * codes, answer timing, half-duplex manners and when new settings take effect. A real
 * servo runs on the host HAL; the test is its UART interrupt and its main loop. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "hal_host.h"
#include "link.h"
#include "proto.h"
#include "servo.h"
#include "vbus.h"

static struct hal hal;
static struct servo s;

static void power_up(const struct board *b)
{
    hal_host_init(&hal);
    hal.now_us = 1000000u;
    servo_init(&s, b, &hal);
}

/* The main loop runs every microsecond up to and including t. */
static void run_until(uint32_t t)
{
    while ((int32_t)(t - hal.now_us) > 0) {
        hal.now_us++;
        servo_poll(&s);
    }
}

/* The host sends a packet back to back at baud, starting now; the servo's UART hears
 * each byte at its end and its main loop keeps running. Returns the last byte's end. */
static uint32_t host_send(const uint8_t *p, size_t n, uint32_t baud)
{
    uint32_t t0 = hal.now_us;
    for (size_t i = 0; i < n; i++) {
        run_until(hal_host_byte_end(t0, baud, (uint32_t)i) - 1u);
        hal.now_us = hal_host_byte_end(t0, baud, (uint32_t)i);
        servo_rx_isr(&s, p[i]);
        servo_poll(&s);
    }
    return hal.now_us;
}

/* Build and send D5 5D id LEN ins params CHK. */
static uint32_t host_cmd(uint8_t id, uint8_t ins, const uint8_t *params, uint8_t n,
                         uint32_t baud)
{
    uint8_t p[64];
    return host_send(p, proto_build_packet(p, id, ins, params, n), baud);
}

static void assert_sent(uint32_t first, const uint8_t *want, size_t n, uint32_t baud)
{
    assert_true(hal.log_len >= first + n);
    for (size_t i = 0; i < n; i++) {
        const struct hal_tx_byte *b = hal_host_tx(&hal, first + (uint32_t)i);
        assert_int_equal(b->byte, want[i]);
        assert_int_equal(b->baud, baud);
    }
}

static const uint8_t PING1_ANSWER[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x00, 0x05};
static const uint8_t OK1[] = {0xD5, 0x5D, 0x01, 0x02, 0x00, 0x03};

/* ---- the answer buffer ------------------------------------------------------------ */

/* Issue 25: PROTO_STATUS_MAX was written by hand (5 + 50 + 1); a register added at 50 or
 * above would have made a whole-table READ, which the SDK sends, overflow link.tx into the
 * next member of struct servo (ASan cannot see inside one struct). It is derived from the
 * table now: the READ the SDK sends fills the buffer exactly, byte for byte. */
static void a_whole_table_read_fills_the_answer_buffer_exactly(void **state)
{
    (void)state;
    power_up(&board_arm);
    const uint8_t rd[2] = {0, REGS_SIZE};
    uint32_t first = hal.log_len;
    host_cmd(1, INS_READ, rd, 2, board_arm.default_baud);
    run_until(hal.now_us + 200000u);
    assert_int_equal(s.link.tx_len, sizeof s.link.tx);
    assert_int_equal(hal.log_len - first, sizeof s.link.tx);
    uint8_t want[PROTO_STATUS_MAX];
    uint8_t table[REGS_SIZE];
    regs_read(&s.regs, 0, REGS_SIZE, table);
    proto_build_packet(want, 1, 0, table, REGS_SIZE);
    assert_sent(first, want, sizeof want, board_arm.default_baud);
    const uint8_t past[2] = {1, REGS_SIZE}; /* one byte more: refused, nothing overflows */
    first = hal.log_len;
    host_cmd(1, INS_READ, past, 2, board_arm.default_baud);
    run_until(hal.now_us + 200000u);
    const uint8_t err[] = {0xD5, 0x5D, 0x01, 0x02, 0x20, 0x23};
    assert_sent(first, err, sizeof err, board_arm.default_baud);
}

/* ---- pure functions -------------------------------------------------------------- */

static void baud_table(void **state)
{
    (void)state;
    const uint32_t table[] = {0, 2400, 9600, 38400, 115200, 256000,
                              460800, 896000, 921600, 1280000, 1792000};
    const struct board *const *bs = board_all;
    for (size_t b = 0; b < BOARD_COUNT; b++) {
        assert_int_equal(link_baud(bs[b], 0), b == 0 ? 115200 : 9600);
        for (uint8_t c = 1; c <= 10; c++)
            assert_int_equal(link_baud(bs[b], c), table[c]);
        assert_int_equal(link_baud(bs[b], 11), 0);
        assert_int_equal(link_baud(bs[b], 0xFF), 0);
    }
}

static void bytes_on_the_wire(void **state)
{
    (void)state;
    assert_int_equal(link_bytes_us(9600, 1), 1042);  /* 1041.7 rounded up */
    assert_int_equal(link_bytes_us(9600, 7), 7292);  /* 7291.7 */
    assert_int_equal(link_bytes_us(9600, 9), 9375);
    assert_int_equal(link_bytes_us(115200, 1), 87);
    assert_int_equal(link_bytes_us(1000000, 3), 30);
    assert_int_equal(link_bytes_us(1792000, 56), 313); /* 312.5 */
    assert_int_equal(link_bytes_us(2400, 0), 0);
}

/* ---- answer timing (§3.2) ----------------------------------------------------------- */

static void answer_starts_after_return_delay(void **state)
{
    (void)state;
    power_up(&board_foot); /* delay 16 x 500 us */
    const uint8_t ping[] = {0xD5, 0x5D, 0x01, 0x02, 0x01, 0x04};
    uint32_t end = host_send(ping, sizeof ping, 9600);
    run_until(end + 7999u);
    assert_int_equal(hal.sends, 0);
    assert_int_equal(hal.log_len, 0);
    run_until(end + 8000u);
    assert_int_equal(hal.sends, 1);
    assert_int_equal(hal_host_tx(&hal, 0)->start_us, end + 8000u);
    assert_sent(0, PING1_ANSWER, sizeof PING1_ANSWER, 9600);

    /* The base answers after 4 ms at 115200. */
    power_up(&board_base);
    end = host_send(ping, sizeof ping, 115200);
    run_until(end + 3999u);
    assert_int_equal(hal.sends, 0);
    run_until(end + 4000u);
    assert_int_equal(hal.sends, 1);
    assert_int_equal(hal_host_tx(&hal, 0)->start_us, end + 4000u);
    assert_sent(0, PING1_ANSWER, sizeof PING1_ANSWER, 115200);
}

static void delay_zero_answers_at_once(void **state)
{
    (void)state;
    power_up(&board_foot);
    const uint8_t zero[] = {REG_RETURN_DELAY, 0};
    uint32_t end = host_cmd(0x01, INS_WRITE, zero, 2, 9600);
    run_until(end + 30000u);
    assert_int_equal(hal.sends, 1);
    assert_int_equal(hal_host_tx(&hal, 0)->start_us, end + 8000u); /* the old delay */
    uint32_t first = hal.log_len;
    end = host_cmd(0x01, INS_PING, 0, 0, 9600);
    run_until(end + 20000u);
    assert_int_equal(hal.sends, 2);
    uint32_t start = hal_host_tx(&hal, first)->start_us;
    assert_true(start >= end);
    assert_true(start - end < 100u); /* §3.2: target under 100 us */
}

static void no_answer_while_a_frame_arrives(void **state)
{
    (void)state;
    power_up(&board_foot);
    uint32_t end = host_cmd(0x01, INS_PING, 0, 0, 9600);
    /* 5 ms later, a READ for servo 2 starts; its header has been heard, and it is still
     * arriving, when the answer is due. */
    run_until(end + 5000u);
    const uint8_t read2[] = {0xD5, 0x5D, 0x02, 0x04, 0x02, 0x10, 0x02, 0x1A};
    uint32_t other_end = host_send(read2, sizeof read2, 9600);
    assert_true(other_end > end + 8000u);
    run_until(other_end + 1u);
    assert_int_equal(hal.sends, 1);
    /* Not before the frame's last byte; at the first main-loop pass after it. */
    uint32_t start = hal_host_tx(&hal, 0)->start_us;
    assert_true(start >= other_end);
    assert_true(start <= other_end + 1u);
    assert_sent(0, PING1_ANSWER, sizeof PING1_ANSWER, 9600);
    run_until(other_end + 60000u);
    assert_int_equal(hal.sends, 1); /* the READ was not ours */
}

static void stalled_frame_delays_answer_until_time_out(void **state)
{
    (void)state;
    power_up(&board_foot);
    uint32_t end = host_cmd(0x01, INS_PING, 0, 0, 9600);
    run_until(end + 4000u);
    const uint8_t partial[] = {0xD5, 0x5D, 0x02};
    uint32_t last = host_send(partial, sizeof partial, 9600);
    assert_true(last < end + 8000u); /* heard before the answer is due */
    /* Byte times are byte ends; the time-out is idle line after the last one. */
    uint32_t gap = frame_rx_gap_us(9600) + link_bytes_us(9600, 1);
    run_until(last + gap);
    assert_int_equal(hal.sends, 0); /* the line may still carry the rest */
    run_until(last + gap + 2u);
    assert_int_equal(hal.sends, 1);
    assert_true(hal_host_tx(&hal, 0)->start_us > last + gap);
    assert_sent(0, PING1_ANSWER, sizeof PING1_ANSWER, 9600);
}

/* ---- new settings take effect after the answer (§1) -------------------------------- */

/* Run until the answer in progress has left the wire, checking at every step that the
 * UART's baud and the settings in force have not changed yet. */
static uint32_t run_through_answer(uint32_t old_baud, uint8_t old_id)
{
    uint32_t t_limit = hal.now_us + 200000u;
    while (hal.sends == 0 || hal_uart_tx_busy(&hal) || s.link.state != LINK_IDLE) {
        assert_int_equal(hal.baud, old_baud);
        assert_int_equal(s.link.baud, old_baud);
        assert_int_equal(s.link.id, old_id);
        assert_true((int32_t)(t_limit - hal.now_us) > 0);
        hal.now_us++;
        servo_poll(&s);
    }
    return hal.tx_end_us;
}

static void baud_change_after_answer_is_out(void **state)
{
    (void)state;
    power_up(&board_foot);
    const uint8_t baud4[] = {REG_BAUD_RATE, 4};
    uint32_t end = host_cmd(0x01, INS_WRITE, baud4, 2, 9600);
    uint32_t sets = hal.baud_sets;
    uint32_t tx_end = run_through_answer(9600, 1);
    assert_sent(0, OK1, sizeof OK1, 9600);
    assert_int_equal(hal_host_tx(&hal, 0)->start_us, end + 8000u);
    assert_int_equal(tx_end, hal_host_byte_end(end + 8000u, 9600, 5));
    /* Latched at the first main-loop pass after the last stop bit, not before. */
    assert_int_equal(hal.now_us, tx_end);
    assert_int_equal(hal.baud, 115200);
    assert_int_equal(s.link.baud, 115200);
    assert_int_equal(hal.baud_sets, sets + 1u);
    assert_int_equal(s.rx.gap_us, frame_rx_gap_us(115200));
    /* Now it talks at 115200. */
    uint32_t first = hal.log_len;
    end = host_cmd(0x01, INS_PING, 0, 0, 115200);
    run_until(end + 20000u);
    assert_sent(first, PING1_ANSWER, sizeof PING1_ANSWER, 115200);
}

static void id_change_after_answer_is_out(void **state)
{
    (void)state;
    power_up(&board_foot);
    const uint8_t id7[] = {REG_ID, 7};
    host_cmd(0x01, INS_WRITE, id7, 2, 9600);
    run_through_answer(9600, 1);
    assert_sent(0, OK1, sizeof OK1, 9600); /* from the old ID */
    assert_int_equal(s.link.id, 7);
    uint32_t first = hal.log_len;
    uint32_t end = host_cmd(0x01, INS_PING, 0, 0, 9600);
    run_until(end + 40000u);
    assert_int_equal(hal.log_len, first); /* 1 is not its ID any more */
    end = host_cmd(0x07, INS_PING, 0, 0, 9600);
    run_until(end + 40000u);
    const uint8_t ans7[] = {0xD5, 0x5D, 0x07, 0x03, 0x01, 0x00, 0x0B};
    assert_sent(first, ans7, sizeof ans7, 9600);
}

static void return_delay_change_after_answer_is_out(void **state)
{
    (void)state;
    power_up(&board_foot);
    const uint8_t d2[] = {REG_RETURN_DELAY, 2};
    uint32_t end = host_cmd(0x01, INS_WRITE, d2, 2, 9600);
    run_through_answer(9600, 1);
    assert_int_equal(hal_host_tx(&hal, 0)->start_us, end + 8000u);
    uint32_t first = hal.log_len;
    end = host_cmd(0x01, INS_PING, 0, 0, 9600);
    run_until(end + 20000u);
    assert_int_equal(hal_host_tx(&hal, first)->start_us, end + 1000u);
}

static void status_level_change_after_answer_is_out(void **state)
{
    (void)state;
    power_up(&board_foot);
    const uint8_t lvl0[] = {REG_STATUS_RETURN_LEVEL, 0};
    host_cmd(0x01, INS_WRITE, lvl0, 2, 9600);
    run_through_answer(9600, 1);
    assert_sent(0, OK1, sizeof OK1, 9600); /* the write itself is still answered */
    uint32_t first = hal.log_len;
    const uint8_t delay3[] = {REG_RETURN_DELAY, 3};
    uint32_t end = host_cmd(0x01, INS_WRITE, delay3, 2, 9600);
    run_until(end + 40000u);
    assert_int_equal(hal.log_len, first); /* level 0: silent */
    assert_int_equal(s.regs.mem[REG_RETURN_DELAY], 3); /* but executed */
    end = host_cmd(0x01, INS_PING, 0, 0, 9600);
    run_until(end + 40000u);
    assert_sent(first, PING1_ANSWER, sizeof PING1_ANSWER, 9600); /* PING always */
}

static void unanswered_change_applies_at_once(void **state)
{
    (void)state;
    power_up(&board_foot);
    /* A broadcast is never answered, so its new baud applies straight away. */
    const uint8_t baud3[] = {REG_BAUD_RATE, 3};
    uint32_t end = host_cmd(PROTO_ID_BROADCAST, INS_WRITE, baud3, 2, 9600);
    run_until(end + 2u);
    assert_int_equal(hal.baud, 38400);
    assert_int_equal(s.link.baud, 38400);
    assert_int_equal(hal.sends, 0);
}

/* ---- a fall-back clock (issue 30) -------------------------------------------------- */

/* Which baud codes a 16x-oversampling UART on each STM32 clock makes within 2 %, as
 * hal/stm32f1/README.md states them: HSE-PLL 72 MHz and HSI-PLL 64 MHz all of them,
 * plain HSI 8 MHz codes 0-5 (460800 is 2.1 % off; 896000 and up exceed its 500 kBd). */
static void fall_back_clocks_reach_the_codes_the_readme_says(void **state)
{
    (void)state;
    static const struct {
        uint32_t hz;
        uint16_t reached; /* bit c: code c */
    } clocks[] = {{72000000u, 0x07FF}, {64000000u, 0x07FF}, {8000000u, 0x003F},
                  {0, 0x07FF}};
    for (size_t c = 0; c < sizeof clocks / sizeof clocks[0]; c++) {
        power_up(&board_foot);
        hal.uart_clock_hz = clocks[c].hz;
        for (uint8_t code = 0; code <= 10; code++) {
            uint8_t write[] = {code};
            bool ok = link_baud_reachable(&s, REG_BAUD_RATE, write, 1);
            assert_int_equal(ok, (clocks[c].reached >> code) & 1u);
        }
        /* A write that leaves register 4 alone is never refused for it; one that spans
         * it is judged by its code. */
        const uint8_t id_only[] = {7};
        assert_true(link_baud_reachable(&s, REG_ID, id_only, 1));
        const uint8_t id_baud_delay[] = {7, 10, 16};
        assert_int_equal(link_baud_reachable(&s, REG_ID, id_baud_delay, 3),
                         (clocks[c].reached >> 10) & 1u);
        assert_true(link_baud_reachable(&s, REG_RETURN_DELAY, id_baud_delay, 1));
    }
}

/* On the 8 MHz fall-back a WRITE of a code it cannot make is an instruction error and
 * changes nothing; a code it makes is taken, and the servo then talks at it. */
static void a_code_the_clock_cannot_make_is_refused(void **state)
{
    (void)state;
    power_up(&board_foot);
    hal.uart_clock_hz = 8000000u;
    uint8_t refused[8];
    uint16_t n = proto_build_packet(refused, 0x01, ERR_INSTRUCTION, 0, 0);
    for (uint8_t code = 6; code <= 10; code++) {
        uint32_t first = hal.log_len;
        const uint8_t w[] = {REG_BAUD_RATE, code};
        uint32_t end = host_cmd(0x01, INS_WRITE, w, 2, 9600);
        run_until(end + 20000u);
        assert_sent(first, refused, n, 9600);
        assert_int_equal(s.regs.mem[REG_BAUD_RATE], 0);
        assert_int_equal(hal.baud, 9600);
    }
    /* REG WRITE holds it, ACTION refuses it. */
    uint32_t first = hal.log_len;
    const uint8_t held[] = {REG_BAUD_RATE, 8};
    run_until(host_cmd(0x01, INS_REG_WRITE, held, 2, 9600) + 20000u);
    run_until(host_cmd(0x01, INS_ACTION, 0, 0, 9600) + 20000u);
    assert_sent(first + 6u, refused, n, 9600);
    assert_int_equal(s.regs.mem[REG_BAUD_RATE], 0);
    /* 256000 is 0.8 % off at 8 MHz: taken. */
    first = hal.log_len;
    const uint8_t baud5[] = {REG_BAUD_RATE, 5};
    run_until(host_cmd(0x01, INS_WRITE, baud5, 2, 9600) + 20000u);
    assert_sent(first, OK1, sizeof OK1, 9600);
    assert_int_equal(hal.baud, 256000);
}

/* ---- broadcast PING (§4.1) ---------------------------------------------------------- */

static void broadcast_ping_slot_per_id(void **state)
{
    (void)state;
    const uint8_t ids[] = {0, 1, 3, 20};
    for (size_t k = 0; k < sizeof ids; k++) {
        power_up(&board_foot);
        s.regs.mem[REG_ID] = ids[k];
        link_latch(&s);
        uint32_t end = host_cmd(PROTO_ID_BROADCAST, INS_PING, 0, 0, 9600);
        uint32_t due = end + 8000u + ids[k] * link_bytes_us(9600, 9);
        run_until(due - 1u);
        assert_int_equal(hal.sends, 0);
        run_until(due);
        assert_int_equal(hal.sends, 1);
        assert_int_equal(hal_host_tx(&hal, 0)->start_us, due);
        uint8_t want[7] = {0xD5, 0x5D, ids[k], 0x03, 0x01, 0x00, 0};
        want[6] = proto_sum(&want[2], 4);
        assert_sent(0, want, sizeof want, 9600);
    }
}

static struct vbus bus;

static void broadcast_ping_discovers_bus_without_collisions(void **state)
{
    (void)state;
    vbus_init(&bus);
    vbus_add(&bus, &board_arm, 3);
    vbus_add(&bus, &board_foot, 1);
    vbus_add(&bus, &board_wrist, 2);
    vbus_run_until(&bus, 100000u);
    const uint8_t ping[] = {0xD5, 0x5D, 0xFE, 0x02, 0x01, 0x01};
    vbus_host_send(&bus, ping, sizeof ping);
    vbus_run_until(&bus, bus.now_us + 100000u);
    assert_int_equal(bus.collisions, 0);
    assert_int_equal(vbus_host_pending(&bus), 21);
    for (uint8_t id = 1; id <= 3; id++) {
        uint8_t want[7] = {0xD5, 0x5D, id, 0x03, 0x01, 0x00, 0};
        want[6] = proto_sum(&want[2], 4);
        for (size_t i = 0; i < 7; i++)
            assert_int_equal(vbus_host_next(&bus)->byte, want[i]);
    }
}

/* A foot at ID 200 turning in speed mode at 9600 baud, heartbeat on. */
static struct node *turning_at_200(void)
{
    vbus_init(&bus);
    bus.step_us = 100;
    vbus_add(&bus, &board_foot, 200);
    struct node *n = &bus.node[0];
    uint8_t pkt[16];
    const uint8_t wheel[] = {REG_CW_LIMIT, 0, 0, 0, 0}, speed[] = {REG_MOVING_SPEED, 120, 0};
    vbus_host_send(&bus, pkt, proto_build_packet(pkt, 200, INS_WRITE, wheel, sizeof wheel));
    vbus_run_until(&bus, bus.now_us + 30000u);
    vbus_host_send(&bus, pkt, proto_build_packet(pkt, 200, INS_WRITE, speed, sizeof speed));
    vbus_run_until(&bus, bus.now_us + 300000u);
    assert_true(n->hal.motor.enabled && n->hal.motor.duty > 0); /* premise: turning */
    while (vbus_host_pending(&bus))
        (void)vbus_host_next(&bus);
    return n;
}

/* Issue 25: a servo waiting to answer a broadcast PING in its slot (ID x slot: 1.9 s for
 * ID 200 at 9600 baud) executed nothing meanwhile: a stop sent 0.2 s after the PING ran
 * 1.7 s late. Rule 3: speed 0 stops at once, whatever answer waits. A broadcast stop (no
 * answer of its own) leaves the PING's answer to come in its slot; a stop addressed to
 * the servo is answered, and that answer replaces the waiting one (docs/decisions.md). */
static void a_stop_during_a_broadcast_ping_slot_acts_at_once(void **state)
{
    (void)state;
    uint8_t pkt[16];
    const uint8_t stop[] = {REG_MOVING_SPEED, 0, 0};
    for (int addressed = 0; addressed < 2; addressed++) {
        struct node *n = turning_at_200();
        const uint8_t ping[] = {0xD5, 0x5D, 0xFE, 0x02, 0x01, 0x01};
        vbus_host_send(&bus, ping, sizeof ping);
        uint32_t slot = bus.now_us + 8000u + 200u * link_bytes_us(9600, 9);
        vbus_run_until(&bus, bus.now_us + 200000u);
        uint8_t id = addressed ? 200u : PROTO_ID_BROADCAST;
        vbus_host_send(&bus, pkt, proto_build_packet(pkt, id, INS_WRITE, stop, sizeof stop));
        vbus_run_until(&bus, bus.now_us + 1000u); /* one control tick */
        assert_false(n->hal.motor.enabled);
        assert_int_equal(n->hal.motor.duty, 0);
        vbus_run_until(&bus, slot + 20000u);
        uint8_t got[8];
        uint32_t len = 0;
        while (vbus_host_pending(&bus) && len < sizeof got)
            got[len++] = vbus_host_next(&bus)->byte;
        const uint8_t ping_ok[] = {0xD5, 0x5D, 200, 0x03, 0x01, 0x00, 0xCC};
        const uint8_t write_ok[] = {0xD5, 0x5D, 200, 0x02, 0x00, 0xCA};
        if (addressed) { /* its own answer, after the return delay; the slot's replaced */
            assert_int_equal(len, sizeof write_ok);
            assert_memory_equal(got, write_ok, sizeof write_ok);
        } else { /* the PING's answer in its slot */
            assert_int_equal(len, sizeof ping_ok);
            assert_memory_equal(got, ping_ok, sizeof ping_ok);
        }
    }
}

/* ... and the READs a host sends meanwhile are executed: they feed the heartbeat, so a
 * moving servo the host keeps talking to is not stopped by it (it was: 1.9 s of frames
 * queued behind the slot, the heartbeat expired at 0.5 s). */
static void reads_during_a_broadcast_ping_slot_feed_the_heartbeat(void **state)
{
    (void)state;
    struct node *n = turning_at_200();
    const uint8_t ping[] = {0xD5, 0x5D, 0xFE, 0x02, 0x01, 0x01};
    vbus_host_send(&bus, ping, sizeof ping);
    uint8_t pkt[16];
    const uint8_t rd[] = {REG_MOVING, 1};
    for (int i = 0; i < 15; i++) {
        vbus_run_until(&bus, bus.now_us + 100000u);
        vbus_host_send(&bus, pkt, proto_build_packet(pkt, 200, INS_READ, rd, sizeof rd));
    }
    vbus_run_until(&bus, bus.now_us + 50000u);
    assert_true(n->hal.motor.enabled && n->hal.motor.duty > 0); /* still turning */
    uint32_t answers = 0;
    while (vbus_host_pending(&bus))
        answers += vbus_host_next(&bus)->byte == 0xD5u;
    assert_int_equal(answers, 15); /* each READ answered */
}

/* Two servos at one ID (a factory-fresh bus) answer a READ at their own return delays:
 * the later one hears the earlier one's answer, a frame to its ID with the ERR byte where
 * an instruction goes (0x00: none), or garbled. Such a frame got an error answer that
 * replaced the READ's waiting answer, so the host saw one servo (issue 27's duplicate
 * detection, test_truth.py, failed). An error answer never replaces one that waits. */
static void an_error_frame_never_replaces_a_waiting_answer(void **state)
{
    (void)state;
    for (int garbled = 0; garbled < 2; garbled++) {
        vbus_init(&bus);
        vbus_add(&bus, &board_foot, 1);
        uint8_t pkt[16];
        const uint8_t delay[] = {REG_RETURN_DELAY, 150}; /* 75 ms */
        vbus_host_send(&bus, pkt, proto_build_packet(pkt, 1, INS_WRITE, delay, sizeof delay));
        vbus_run_until(&bus, bus.now_us + 100000u);
        while (vbus_host_pending(&bus))
            (void)vbus_host_next(&bus);
        const uint8_t read[] = {REG_RETURN_DELAY, 1};
        vbus_host_send(&bus, pkt, proto_build_packet(pkt, 1, INS_READ, read, sizeof read));
        vbus_run_until(&bus, bus.now_us + 10000u);
        /* the other servo's answer (ERR 0, one byte), 10 ms later */
        uint8_t other[] = {0xD5, 0x5D, 0x01, 0x03, 0x00, 0x10, 0x14};
        if (garbled)
            other[5] ^= 0x40u;
        vbus_host_send(&bus, other, sizeof other);
        vbus_run_until(&bus, bus.now_us + 120000u);
        uint8_t got[8];
        uint32_t len = 0;
        while (vbus_host_pending(&bus) && len < sizeof got)
            got[len++] = vbus_host_next(&bus)->byte;
        const uint8_t read_ok[] = {0xD5, 0x5D, 0x01, 0x03, 0x00, 150, 0x9A};
        assert_int_equal(len, sizeof read_ok);
        assert_memory_equal(got, read_ok, sizeof read_ok);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_whole_table_read_fills_the_answer_buffer_exactly),
        cmocka_unit_test(baud_table),
        cmocka_unit_test(bytes_on_the_wire),
        cmocka_unit_test(answer_starts_after_return_delay),
        cmocka_unit_test(delay_zero_answers_at_once),
        cmocka_unit_test(no_answer_while_a_frame_arrives),
        cmocka_unit_test(stalled_frame_delays_answer_until_time_out),
        cmocka_unit_test(baud_change_after_answer_is_out),
        cmocka_unit_test(id_change_after_answer_is_out),
        cmocka_unit_test(return_delay_change_after_answer_is_out),
        cmocka_unit_test(status_level_change_after_answer_is_out),
        cmocka_unit_test(unanswered_change_applies_at_once),
        cmocka_unit_test(fall_back_clocks_reach_the_codes_the_readme_says),
        cmocka_unit_test(a_code_the_clock_cannot_make_is_refused),
        cmocka_unit_test(broadcast_ping_slot_per_id),
        cmocka_unit_test(broadcast_ping_discovers_bus_without_collisions),
        cmocka_unit_test(a_stop_during_a_broadcast_ping_slot_acts_at_once),
        cmocka_unit_test(reads_during_a_broadcast_ping_slot_feed_the_heartbeat),
        cmocka_unit_test(an_error_frame_never_replaces_a_waiting_answer),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
