/* node.h - one servo on a host bus: the firmware core on its own host HAL, the board it
 * is built for, and how much of what it sent the bus has taken. Both buses run their
 * servos through this: vbus.c (virtual time, the tests) and servo-sim (real time, TCP).
 *
 * A node lives as the MCU does: power-on through the bootloader model (the factory image
 * in a blank application slot), a main-loop pass at a given time, and a restart when
 * the core calls hal_restart(). Its ID is set the one way a factory would: a WRITE of
 * register 3 over its own UART (node_set_id). What it sends is in its HAL's tx log; the
 * bus takes it from there in time order across nodes (node_tx_next). */
#ifndef NODE_H
#define NODE_H

#include <stdbool.h>
#include <stdint.h>

#include "board.h"
#include "hal_host.h"
#include "servo.h"

/* Longest a node_set_id() takes of the node's own clock (a WRITE and its answer at the
 * slowest baud, after the longest return delay). */
#define NODE_SET_ID_US 200000u

struct node {
    struct hal hal;
    struct servo servo;
    const struct board *board;
    uint32_t log_seen; /* hal.log bytes the bus has taken (node_tx_take) */
};

/* A servo of board b with blank flash, its clock at now_us; not powered yet. */
void node_init(struct node *n, const struct board *b, uint32_t now_us);

/* Power-up: a blank application slot gets the factory image (what the factory
 * programs), then the bootloader's decision (servo_power_on): the application, or update
 * mode. */
void node_power_on(struct node *n);

/* A reset (hal_restart(), or a power cycle): the UART and the clock's state go, the flash
 * and the plant stay, the bootloader's decision runs again, at the node's present time. */
void node_restart(struct node *n);

/* One main-loop pass at now_us (not before the node's present time); a hal_restart()
 * made in it restarts the node. None while a flash erase stalls the loop (hal_host.h). */
void node_step(struct node *n, uint32_t now_us);

/* Give the servo the ID it will keep, as a factory configures a fresh one: a WRITE of
 * register 3 to its present ID, fed to its UART, then its main loop in steps of 100 us of
 * its own clock until the answer is out and the new ID is in force (at most
 * NODE_SET_ID_US). The store saves it like any setting. The answer is taken and
 * dropped. False if the servo did not take it (update mode, or an ID above 253). */
bool node_set_id(struct node *n, uint8_t id);

/* Its next byte the bus has not taken, or 0. */
const struct hal_tx_byte *node_tx_peek(const struct node *n);

/* The bus has taken that byte. */
void node_tx_take(struct node *n);

/* Output merging: of count nodes, the index of the one whose next byte not yet taken
 * starts first, if it starts by until_us (ties: the lower index); -1 if none does.
 * Taking bytes in this order puts every node's bytes on the wire in time order. */
int node_tx_next(struct node *const *nodes, unsigned count, uint32_t until_us);

#endif
