/* bus.h - the servos of servo-sim on one wire, in real time.
 *
 * Each servo is a node (hal/host/node.h) whose clock (hal.now_us) is CLOCK_MONOTONIC in
 * microseconds, plus a configuration window before it, from HAL_HOST_CLOCK_START: 10 s
 * before the 32-bit clock wraps, so every session crosses the wrap. When a servo switches
 * its RS485 terminator (register 20), stderr says `servo-sim: ID N terminator on|off`. The line is hal/host/wire.h: what
 * every servo sends goes on it at the servo's baud, two servos sending at once garble
 * each other (the AND of the talkers, RS485 idle high), and every servo hears the line
 * through its own UART at its own baud (register 4): other servos' answers included, its
 * own echo and framing errors dropped, as the STM32 port does.
 *
 * The host, i.e. the TCP client, is one of two kinds (client.c tells them apart):
 * - raw (tcp://): no baud rate. Its bytes reach every servo whatever the servo's baud,
 *   paced as a UART at that baud would deliver them: back to back from when they arrive,
 *   each taking its 10 bit-times (so a burst sent in one socket write behaves as on a real
 *   bus, where the servo's main loop takes each frame before the next has arrived). They
 *   do not go on the line (no collisions). It hears the line at every baud (each byte at
 *   the baud of the talker whose start bit it is). When a servo's queue of raw bytes is
 *   full (BUS_RAW_MAX), servo-sim stops reading the socket: TCP's flow control paces a
 *   client that sends faster than the wire.
 * - a UART at a baud the client sets (RFC 2217, rfc2217://): its bytes go on the line at
 *   that baud, back to back, from when they arrive; it hears the line at that baud. A
 *   servo at another baud receives what its UART would make of them: framing errors and
 *   garbage, so it does not answer, and its answers reach the host as garbage.
 *
 * Time runs as discrete events in order, up to the real clock: a servo's main-loop pass
 * at every BUS_TICK_US, when its answer falls due, and when its UART completes a byte (from
 * the line, or a raw client's); the host's UART completing a byte. A new byte only ever starts at such an event, so a
 * byte is decoded from a line that is final up to its stop bit. A servo's answer starts
 * up to BUS_LOOP_US plus 1/16 bit after it falls due (the MCU's main-loop latency and its
 * receiver's sampling phase), drawn per answer: two servos with one ID answer a few
 * microseconds apart, so their answers garble each other where a bit is shorter than
 * about twice that (from 115200 baud up), and superimpose cleanly where it is longer.
 * When the loop wakes late (a loaded host), the events run late in their order; beyond
 * BUS_CATCH_UP_US behind (the process was stopped) the clock jumps.
 *
 * The motor and the photo switches of each servo are the host HAL's plant
 * (hal_host_attach_board()), integrated up to the real clock.
 *
 * A frame a servo's receiver had to drop (no room in its queue: frame_rx.h, overruns) is
 * reported on stderr, "servo-sim: ID n dropped k frame(s): ...", so a host can see it: at
 * most a line per servo per 100 ms, and what is left when servo-sim ends. */
#ifndef BUS_H
#define BUS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "node.h"
#include "state.h"
#include "wire.h"

#define BUS_TICK_US 500u      /* main-loop period when nothing is due sooner */
#define BUS_LOOP_US 8u        /* the MCU's main-loop latency: a reply starts up to this late */
#define BUS_CATCH_UP_US 200000 /* a bus this far behind real time jumps */
#define BUS_RAW_MAX 65536u     /* power of two: a raw client's bytes not yet delivered */
#define BUS_EXT_MAX 8u         /* --uart nodes */
#define BUS_EXT_OUT 8192u      /* bytes an external UART heard, not yet written to it */

struct sim_servo {
    struct node node;
    uint8_t arg_id;      /* as given on the command line; names the state file */
    struct state_file state;
    struct wire_rx rx;   /* its UART on the line */
    bool terminator;     /* the RS485 terminator as last reported on stderr */
    int tokens;          /* its commit tokens as last reported (-1: not yet) */
    int moving;          /* register 42 as last reported (-1: not yet) */
    int64_t send_t0_ns;  /* the transmission its bytes belong to (exact bit times) */
    uint32_t send_t0_us, send_baud, send_i;
    uint64_t raw_next;   /* the next raw client byte its UART delivers (a count) */
    int64_t raw_end_ns;  /* when the last one it delivered ended */
    uint32_t drops;      /* its receiver's overruns, as last reported */
    int64_t drops_us;    /* when */
};

/* Add a servo of board b: its state file first (with state_dir), then power-up; a new
 * servo (blank flash) gets arg_id the one way (node_set_id), in virtual time before the
 * real clock starts. uid is its hal_uid(); with uid_names_file its state file's name
 * carries the UID too (several servos of one ID and variant: state.h). Call before
 * bus_start(). */
void bus_add(uint8_t arg_id, const struct board *b, const uint8_t uid[HAL_UID_BYTES],
             bool uid_names_file, const char *state_dir);

/* --report-commits: from now on, each change of a servo's flash commit tokens (a commit
 * spent, a token back) is a line `servo-sim: ID N commit tokens T` on stderr, and each
 * servo's count once at once: what a host's budget estimate is checked against. */
void bus_report_commits(void);

/* --report-moves: from now on, each switch of a servo's register 42 (moving) is a line
 * `servo-sim: ID N moving 0|1 at T us` on stderr, T its virtual clock when the main-loop
 * pass that switched it ran: what make bench's coordinated-start skew is measured from
 * (tools/bench_ids.py). Servos behind --uart are not seen from inside. */
void bus_report_moves(void);

/* The real clock starts: every servo's clock is set to it. */
void bus_start(void);

unsigned bus_count(void);
const struct sim_servo *bus_servo(unsigned i);

/* Microseconds since the start, plus the configuration window (the servos' clocks are
 * this, modulo 2^32, like the HAL's). */
int64_t bus_now(void);

/* Run everything that falls due up to now. */
void bus_advance(int64_t now);

/* Microseconds from now until something falls due (at most BUS_TICK_US). */
uint32_t bus_next_wake(int64_t now);

/* A client connected at now; its kind is not known yet (it is heard as raw). A new
 * connection is a known frame boundary: every servo's receiver drops a frame in
 * progress, so what a client that left mid-frame sent is gone. */
void bus_host_connect(int64_t now);

/* The client is gone: its bytes that have not started on the line are dropped. */
void bus_host_disconnect(int64_t now);

/* The client is a UART at baud (RFC 2217), from now on. */
void bus_host_uart(uint32_t baud);

/* Raw host bytes, arrived at now: every servo receives them at its baud, after what came
 * before (n at most bus_host_raw_room()). */
void bus_host_raw(const uint8_t *in, size_t n, int64_t now);

/* How many raw bytes the servos' queues take now. */
size_t bus_host_raw_room(void);

/* UART host bytes, arrived at now: on the line at the host's baud, after what it sent
 * before. */
void bus_host_send(const uint8_t *in, size_t n, int64_t now);

/* Drop host bytes that have not started on the line yet (RFC 2217 purge). */
void bus_host_purge(int64_t now);

/* Bytes the host's receiver completed (since the last call), into out, at most max (the
 * rest is dropped, as with no client: pass max 0). Returns the count. */
size_t bus_output(uint8_t *out, size_t max);

/* The end: every drop not reported yet is, then the servos go. */
void bus_free(void);

/* External UARTs (servo-sim --uart HOST:PORT[:BAUD], issue 27): a device behind a TCP
 * byte stream, e.g. a QEMU-run arm image's USART1, as a node of the line. Each is a
 * talker and a receiver at its fixed baud (default 9600): its bytes go on the line back
 * to back from when they arrive, so they garble with whatever else is on it, and it
 * hears the line (the servos' answers, an rfc2217 host's bytes) and a raw client's
 * bytes, paced at its baud. Its own timing is its emulator's: what it sends reaches the
 * line as soon as servo-sim reads it. Add before bus_start(). */
void bus_add_ext(int fd, uint32_t baud);
unsigned bus_ext_count(void);
int bus_ext_fd(unsigned e);
/* Bytes read from external UART e at now go on the line. */
void bus_ext_send(unsigned e, const uint8_t *in, size_t n, int64_t now);
/* What external UART e heard since the last call (to be written to its socket). */
size_t bus_ext_output(unsigned e, uint8_t *out, size_t max);

#endif
