/* bus_host.h - a host on the virtual bus (vbus.h), for tests that judge a servo only by
 * what a host sees: instruction packets out, status packets back, the control table as
 * READ returns it. The plant (hal.motor, the sensors) is the test's ground truth; the
 * servo's own state (struct servo) is never looked at. One servo per bus, ID 1.
 *
 * bus_open() powers a fresh servo up on its factory image and switches the link to
 * BUS_FAST_BAUD with return delay 0 (both through the bus, as a host would), so a READ
 * of the whole table takes well under a millisecond of virtual time. */
#ifndef BUS_HOST_H
#define BUS_HOST_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "proto.h"
#include "regs.h"
#include "vbus.h"

#define BUS_ID 1u
#define BUS_FAST_CODE 10u       /* register 4: 1792000 baud (§5.2) */
#define BUS_FAST_BAUD 1792000u
#define BUS_STEP_US 100u        /* main-loop period of the servo */
#define BUS_ANSWER_US 20000u    /* no answer within this: none comes */

static struct vbus bus;

/* Last answer: ERR byte and parameters; -1 from bus_ins() if none or malformed. */
static uint8_t bus_ans[PROTO_STATUS_MAX];
static uint8_t bus_ans_len;

static inline struct hal *bus_hal(void)
{
    return &bus.node[0].hal;
}

static inline void bus_run_ms(uint32_t ms)
{
    vbus_run_until(&bus, bus.now_us + ms * 1000u);
}

/* Drop whatever the servo sent that nobody read. */
static inline void bus_drain(void)
{
    while (vbus_host_pending(&bus))
        (void)vbus_host_next(&bus);
}

/* Send one instruction to ID id and wait for its answer (none for broadcast) to end.
 * Returns the ERR byte (PING: the 0x01 in its place, §4.1), or -1 if no well-formed
 * answer came. */
static inline int bus_ins_to(uint8_t id, uint8_t ins, const uint8_t *par, uint8_t n)
{
    uint8_t pkt[260];
    uint16_t len = proto_build_packet(pkt, id, ins, par, n);
    bus_drain();
    vbus_host_send(&bus, pkt, len);
    bus_ans_len = 0;
    if (id == PROTO_ID_BROADCAST)
        return 0;
    uint8_t got[PROTO_STATUS_MAX];
    uint32_t have = 0, want = 6;
    uint32_t deadline = bus.now_us + BUS_ANSWER_US, end_us = bus.now_us;
    while (have < want && (int32_t)(deadline - bus.now_us) > 0) {
        vbus_run_until(&bus, bus.now_us + 50u);
        while (have < want && vbus_host_pending(&bus)) {
            const struct vbus_byte *w = vbus_host_next(&bus);
            got[have++] = w->byte;
            end_us = w->end_us;
            if (have == 4u)
                want = 4u + got[3];
            if (want > sizeof got)
                return -1;
        }
    }
    vbus_run_until(&bus, end_us); /* the answer is on the wire until its last stop bit */
    if (have < want || have < 6u || got[0] != PROTO_HEADER0 || got[1] != PROTO_HEADER1 ||
        got[2] != id || proto_sum(&got[2], (uint16_t)(have - 3u)) != got[have - 1u])
        return -1;
    bus_ans_len = (uint8_t)(have - 6u);
    memcpy(bus_ans, &got[5], bus_ans_len);
    return got[4];
}

static inline int bus_ins(uint8_t ins, const uint8_t *par, uint8_t n)
{
    return bus_ins_to(BUS_ID, ins, par, n);
}

static inline int bus_write(uint8_t addr, const uint8_t *data, uint8_t n)
{
    uint8_t p[64];
    p[0] = addr;
    memcpy(&p[1], data, n);
    return bus_ins(INS_WRITE, p, (uint8_t)(n + 1u));
}

static inline int bus_w8(uint8_t addr, uint8_t v)
{
    return bus_write(addr, &v, 1);
}

static inline int bus_w16(uint8_t addr, uint16_t v)
{
    uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    return bus_write(addr, d, 2);
}

/* READ of the whole table into t[0..REGS_SIZE); false if no answer. */
static inline bool bus_read_table(uint8_t *t)
{
    uint8_t p[2] = {0, REGS_SIZE};
    bool ok = bus_ins(INS_READ, p, 2) >= 0 && bus_ans_len == REGS_SIZE;
    if (ok)
        memcpy(t, bus_ans, REGS_SIZE);
    else
        memset(t, 0, REGS_SIZE); /* written either way (GCC -O2 sees no uninitialised read) */
    return ok;
}

static inline uint16_t tab16(const uint8_t *t, uint8_t addr)
{
    return (uint16_t)(t[addr] | (t[addr + 1u] << 8));
}

/* The present position as the table reports it (regs_position_addr(), regs.h). */
static inline int32_t tab_position(const struct board *b, const uint8_t *t)
{
    uint8_t a = regs_position_addr(b);
    return regs_position_value(a, tab16(t, a));
}

static inline int32_t tab_speed(const uint8_t *t)
{
    return (int16_t)tab16(t, REG_PRESENT_SPEED);
}

/* After a baud change is answered, the host follows. */
static inline void bus_follow_baud(uint32_t baud)
{
    bus_run_ms(1);
    bus.host_baud = baud;
}

/* A fresh servo of board b on an empty bus, at BUS_FAST_BAUD with return delay 0. */
static inline bool bus_open(const struct board *b)
{
    vbus_init(&bus);
    bus.step_us = BUS_STEP_US;
    bus.host_baud = b->default_baud;
    (void)vbus_add(&bus, b, 0);
    bus_run_ms(5);
    if (bus_w8(REG_RETURN_DELAY, 0) != 0 || bus_w8(REG_BAUD_RATE, BUS_FAST_CODE) != 0)
        return false;
    bus_follow_baud(BUS_FAST_BAUD);
    return bus_ins(INS_PING, NULL, 0) == 1;
}

/* Wait for homing to end, polling register 24 every 100 ms as servoctl home --wait does
 * (the polls keep the heartbeat fed); returns the status nibble (1: still running). */
static inline uint8_t bus_home_wait(uint32_t timeout_ms)
{
    uint8_t p[2] = {REG_HOMING, 1};
    for (uint32_t t = 0; t < timeout_ms; t += 100u) {
        bus_run_ms(100);
        if (bus_ins(INS_READ, p, 2) == 0 && bus_ans_len == 1u && (bus_ans[0] >> 4) != 1u)
            return (uint8_t)(bus_ans[0] >> 4);
    }
    return 1;
}

/* Homing (register 24 := 1), waited for; returns the status nibble. */
static inline uint8_t bus_home(uint32_t timeout_ms)
{
    if (bus_w8(REG_HOMING, 1) != 0)
        return 0xFF;
    return bus_home_wait(timeout_ms);
}

#endif
