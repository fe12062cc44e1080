/* sim.h - what every part of servo-sim shares: its limits and how it fails.
 *
 * servo-sim is the virtual servo bus in real time: host-built servos (the firmware core
 * on the host HAL, hal/host/node.h) behind one TCP port whose byte stream is the bus.
 * Its parts, one job each:
 *   main.c    the command line's order of work, signals, the exit status
 *   args.c    the command line (a contract: README, tools/python/README.md)
 *   state.c   --state-dir: each servo's flash in a file, following every flash operation
 *   bus.c     the servos and the host on one wire (hal/host/wire.h) in real time
 *   client.c  the TCP side: the listening socket, the one client and its kind, the loop
 *   rfc2217.c a Telnet COM-PORT-CONTROL client's protocol (rfc2217:// clients) */
#ifndef SIM_H
#define SIM_H

#define SIM_SERVOS_MAX 254u /* IDs 0-253 */

/* Print "servo-sim: " and one line on stderr, exit with status code (2: a bad command
 * line or a port that cannot be listened on; 1: a failure while running). */
void die(int code, const char *fmt, ...) __attribute__((noreturn, format(printf, 2, 3)));

#endif
