/* args.h - servo-sim's command line:
 *
 *   servo-sim --listen HOST:PORT [--servo ID:VARIANT]... [--state-dir DIR]
 *             [--report-commits]
 *
 * A contract (README, tools/python/README.md, tests/test_sim.py): every error is one
 * line on stderr and exit status 2. */
#ifndef ARGS_H
#define ARGS_H

#include <netinet/in.h>
#include <stdbool.h>
#include <stdint.h>

#include "board.h"
#include "sim.h"

struct servo_arg {
    uint8_t id;
    const struct board *board;
    const char *text; /* as given, for messages */
};

struct sim_args {
    struct sockaddr_in listen;
    const char *listen_text;
    const char *state_dir; /* 0 without --state-dir */
    bool report_commits;   /* --report-commits: each servo's commit tokens on stderr */
    unsigned nservos;      /* at least 1: one arm with ID 1 when none is given */
    struct servo_arg servo[SIM_SERVOS_MAX];
};

/* Parse argv into a (--help prints the usage and exits 0; an error exits 2). */
void args_parse(int argc, char **argv, struct sim_args *a);

#endif
