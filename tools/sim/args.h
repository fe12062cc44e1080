/* args.h - servo-sim's command line:
 *
 *   servo-sim --listen HOST:PORT [--servo ID:VARIANT[:UID]]... [--uart HOST:PORT[:BAUD]]...
 *             [--state-dir DIR] [--report-commits] [--report-moves]
 *
 * --uart: a device behind a TCP byte stream on the line (tools/sim/bus.h bus_add_ext),
 * e.g. a QEMU-run arm image's USART1 (tools/qemu_servo.py), at BAUD (default 9600).
 *
 * Several --servo may share an ID, as a bus of factory-fresh servos does (issue 27):
 * they all answer, and their answers garble. UID: the node's unique identity (hal_uid(),
 * include/ident.h), 24 hex digits, byte 0 first; without it the n-th --servo (from 0)
 * gets args_default_uid(n). Two nodes with one UID are refused.
 *
 * A contract (README, tools/python/README.md, tests/test_sim.py): every error is one
 * line on stderr and exit status 2. */
#ifndef ARGS_H
#define ARGS_H

#include <netinet/in.h>
#include <stdbool.h>
#include <stdint.h>

#include "board.h"
#include "hal.h"
#include "sim.h"

struct servo_arg {
    uint8_t id;
    const struct board *board;
    const char *text; /* as given, for messages */
    bool uid_given;   /* a UID on the command line: it also names the state file */
    uint8_t uid[HAL_UID_BYTES];
};

struct sim_args {
    struct sockaddr_in listen;
    const char *listen_text;
    const char *state_dir; /* 0 without --state-dir */
    bool report_commits;   /* --report-commits: each servo's commit tokens on stderr */
    bool report_moves;     /* --report-moves: each switch of a servo's register 42 on stderr */
    unsigned nservos;      /* at least 1: one arm with ID 1 when none is given */
    struct servo_arg servo[SIM_SERVOS_MAX];
    unsigned nuarts;
    struct sockaddr_in uart[8];
    uint32_t uart_baud[8];
    const char *uart_text[8];
};

/* The UID of the n-th servo when none is given: bytes 0-3 a mix of n (where STM32 UIDs
 * differ, their die's X/Y on the wafer), then a fixed "wafer" and "lot". Deterministic,
 * so a test and a state directory see the same node again. */
void args_default_uid(unsigned n, uint8_t uid[HAL_UID_BYTES]);

/* Parse argv into a (--help prints the usage and exits 0; an error exits 2). */
void args_parse(int argc, char **argv, struct sim_args *a);

#endif
