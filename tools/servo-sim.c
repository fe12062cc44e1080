/* servo-sim.c - the virtual servo bus in real time: host-built servos (the firmware core
 * with the host HAL) behind one TCP port, whose byte stream is the bus.
 *
 *   servo-sim --listen HOST:PORT [--servo ID:VARIANT]... [--state-dir DIR]
 *
 * Bus model (documented in tools/python/README.md):
 * - One TCP client at a time; what it sends is what the host puts on the wire, what it
 *   receives is what the servos put on it. A second client is accepted and closed.
 * - Real time: every servo's clock (hal.now_us) is CLOCK_MONOTONIC in microseconds. The
 *   bytes the client sends are fed to every servo through servo_rx_isr() when they
 *   arrive (TCP has no baud rate, so a request takes no wire time).
 * - Baud rates are ignored on the way in: every servo hears every host byte whatever
 *   its register 4 says. On the way out a servo's answer is paced at its own baud: each
 *   byte is written to the socket once its stop bit has ended (the host HAL's tx log
 *   gives the times). Bytes of several servos are merged in that order, each servo's in
 *   its own order.
 * - Servos do not hear each other (only the host's bytes reach them).
 * - The loop wakes at least every SIM_TICK_US. When it wakes late (a loaded host), each
 *   servo catches up in steps of SIM_TICK_US of its own clock, and an answer that fell
 *   due meanwhile starts at its due time, as the MCU would have run them.
 * - The motor and the photo switches of each servo are the host HAL's plant
 *   (hal_host_attach_board(): arm switches at 0 and 420 degrees, the shaft starting at
 *   90), integrated up to the real clock. The shaft starts there at every start.
 * - --state-dir: each servo's simulated flash (store, both slots, boot record) lives in
 *   DIR/servo-<ID>-<variant>.flash (ID as given on the command line), loaded before
 *   servo_power_on() and written back page by page (pwrite of the changed 1 KiB page in
 *   place) right after every flash operation, so a SIGKILL at any moment is a power cut
 *   between two flash operations.
 *
 * Single-threaded, non-blocking, one ppoll() loop. SIGINT/SIGTERM end it cleanly.
 * Exit status: 0 after a signal, 2 for a bad command line or a port that cannot be
 * listened on, 1 for a failure while running. */
#define _GNU_SOURCE /* ppoll, accept4 */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "board.h"
#include "hal_host.h"
#include "proto.h"
#include "servo.h"

#define SIM_SERVOS_MAX 254u       /* IDs 0-253 */
#define SIM_TICK_US 500u          /* main-loop period when nothing is due sooner */
#define SIM_CATCH_UP_US 200000u   /* a servo this far behind real time jumps */
#define SIM_CONFIG_US 1000000u    /* virtual time reserved for configuring new servos */
#define SIM_OUT_MAX (1u << 20)    /* bytes queued for a client that does not read */
#define SIM_FLASH_BYTES (FLASH_SIM_PAGES * HAL_FLASH_PAGE_BYTES) /* with the boot record */
#define SIM_SLOTS_FLASH_BYTES (HAL_PAGES_ALL * HAL_FLASH_PAGE_BYTES) /* store and slots */
#define SIM_OLD_FLASH_BYTES (HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES) /* store only */

static const char usage[] =
    "usage: servo-sim --listen HOST:PORT [--servo ID:VARIANT]... [--state-dir DIR]";

/* One servo on the bus. */
struct sim_servo {
    uint8_t id; /* as given on the command line; names the state file */
    const struct board *board;
    struct hal hal;
    struct servo servo;
    uint32_t log_seen; /* hal.log bytes already written to the client (or dropped) */
    int state_fd;      /* -1 without --state-dir */
    uint32_t synced_ops; /* hal.flash.ops when the file last matched the flash */
    char *state_path;
    uint8_t saved[FLASH_SIM_PAGES][HAL_FLASH_PAGE_BYTES]; /* what the file holds */
};

static struct sim_servo *servos[SIM_SERVOS_MAX];
static unsigned servo_count;
static struct timespec clock_zero;
static volatile sig_atomic_t stop_signal;

static uint8_t out_buf[SIM_OUT_MAX];
static size_t out_len;

/* Print one line on stderr and exit with status code. */
static void die(int code, const char *fmt, ...) __attribute__((noreturn, format(printf, 2, 3)));
static void die(int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fputs("servo-sim: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    exit(code);
}

/* Microseconds since start, plus the configuration window; wraps at 2^32 like the HAL. */
static uint32_t sim_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    int64_t us = ((int64_t)t.tv_sec - clock_zero.tv_sec) * 1000000 +
                 (t.tv_nsec - clock_zero.tv_nsec) / 1000;
    return (uint32_t)((uint64_t)us + SIM_CONFIG_US);
}

static void on_signal(int sig)
{
    stop_signal = sig;
}

/* ---- Simulated flash in a file ---------------------------------------------------- */

/* Write every page that differs from the file to it, in place. A pwrite() of one 1 KiB
 * page inside one 4 KiB file page reaches the page cache whole or not at all, so a
 * SIGKILL never tears a page; the host kernel keeps the data even if this process dies,
 * so there is no fsync (a host crash is not the power cut being modelled). */
static void state_write(struct sim_servo *v)
{
    if (v->state_fd < 0)
        return;
    for (unsigned p = 0; p < FLASH_SIM_PAGES; p++) {
        if (memcmp(v->hal.flash.mem[p], v->saved[p], HAL_FLASH_PAGE_BYTES) == 0)
            continue;
        ssize_t n = pwrite(v->state_fd, v->hal.flash.mem[p], HAL_FLASH_PAGE_BYTES,
                           (off_t)p * HAL_FLASH_PAGE_BYTES);
        if (n != (ssize_t)HAL_FLASH_PAGE_BYTES)
            die(1, "cannot write %s: %s", v->state_path, n < 0 ? strerror(errno) : "short write");
        memcpy(v->saved[p], v->hal.flash.mem[p], HAL_FLASH_PAGE_BYTES);
    }
    v->synced_ops = v->hal.flash.ops;
}

/* The same, only if the core ran a flash operation since (the usual case: none). */
static void state_sync(struct sim_servo *v)
{
    if (v->hal.flash.ops != v->synced_ops)
        state_write(v);
}

/* The linker routes the core's flash operations here (-Wl,--wrap, tools/CMakeLists.txt)
 * so the file follows the flash operation by operation, not just once per main-loop
 * step: a SIGKILL lands between two operations, as a power cut between them would. */
bool __real_hal_flash_erase(struct hal *h, uint8_t p);
bool __real_hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value);
bool __wrap_hal_flash_erase(struct hal *h, uint8_t p);
bool __wrap_hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value);

static void state_sync_hal(struct hal *h)
{
    for (unsigned i = 0; i < servo_count; i++)
        if (&servos[i]->hal == h)
            state_sync(servos[i]);
}

bool __wrap_hal_flash_erase(struct hal *h, uint8_t p)
{
    bool ok = __real_hal_flash_erase(h, p);
    state_sync_hal(h);
    return ok;
}

bool __wrap_hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value)
{
    bool ok = __real_hal_flash_program(h, p, off, value);
    state_sync_hal(h);
    return ok;
}

/* Open (or create, erased) DIR/servo-<ID>-<variant>.flash into the servo's flash. The
 * file is locked so two simulators cannot share one servo's flash. */
static void state_open(struct sim_servo *v, const char *dir)
{
    size_t len = strlen(dir) + 64u;
    v->state_path = malloc(len);
    if (!v->state_path)
        die(1, "out of memory");
    snprintf(v->state_path, len, "%s/servo-%u-%s.flash", dir, v->id, v->board->name);
    v->state_fd = open(v->state_path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (v->state_fd < 0)
        die(2, "cannot open state file %s: %s", v->state_path, strerror(errno));
    if (flock(v->state_fd, LOCK_EX | LOCK_NB) != 0)
        die(2, "state file %s is in use by another servo-sim", v->state_path);
    struct stat st;
    if (fstat(v->state_fd, &st) != 0)
        die(2, "cannot stat state file %s: %s", v->state_path, strerror(errno));
    if (st.st_size == 0) {
        /* A new servo: erased flash (hal_host_init left it so). */
        if (pwrite(v->state_fd, v->hal.flash.mem, SIM_FLASH_BYTES, 0) != (ssize_t)SIM_FLASH_BYTES)
            die(2, "cannot write state file %s: %s", v->state_path, strerror(errno));
        memcpy(v->saved, v->hal.flash.mem, sizeof v->saved);
        return;
    }
    /* A file from before the image slots holds the store pages only: keep them, the
     * slots start erased (and get the factory image); one from before the boot record
     * holds store and slots: the record starts erased (no start counted). */
    size_t bytes = (size_t)st.st_size;
    if (bytes != SIM_FLASH_BYTES && bytes != SIM_SLOTS_FLASH_BYTES &&
        bytes != SIM_OLD_FLASH_BYTES)
        die(2, "state file %s has %lld bytes, not %u: not a servo-sim flash image",
            v->state_path, (long long)st.st_size, SIM_FLASH_BYTES);
    if (pread(v->state_fd, v->hal.flash.mem, bytes, 0) != (ssize_t)bytes)
        die(2, "cannot read state file %s: %s", v->state_path, strerror(errno));
    memcpy(v->saved, v->hal.flash.mem, bytes);
    if (bytes < SIM_FLASH_BYTES) /* the pages it lacks are written on sync */
        memset(v->saved[bytes / HAL_FLASH_PAGE_BYTES], 0, SIM_FLASH_BYTES - bytes);
}

static bool pages_blank(const struct sim_servo *v, unsigned first, unsigned count)
{
    const uint8_t *m = &v->hal.flash.mem[first][0];
    for (unsigned i = 0; i < count * HAL_FLASH_PAGE_BYTES; i++)
        if (m[i] != 0xFFu)
            return false;
    return true;
}

/* A servo whose application slot was never written gets what the factory programs
 * (hal_host_program_factory): an image of this board at this build's version, which
 * boot_install() checks like any. An update replaces it; a damaged one is left as it is
 * (the servo then stays in update mode). */
static void factory_program(struct sim_servo *v)
{
    hal_host_program_factory(&v->hal, v->board);
    state_write(v); /* a programmer's write, not a counted flash operation */
}

/* ---- Servos ---------------------------------------------------------------------- */

/* Run one servo's main loop at now; dispatch frames that wait while the link is free.
 * An answer that fell due since the last step is started at its due time first, as the
 * MCU's own clock would start it: a late start would slide one servo's broadcast-PING
 * slot into the next one's. */
static void servo_run_once(struct sim_servo *v)
{
    servo_step(&v->servo);
    if (v->hal.restart_requested) { /* hal_restart(): the MCU resets, the bootloader runs */
        hal_host_reboot(&v->hal);
        servo_power_on(&v->servo, v->board, &v->hal);
    }
}

static void servo_run_at(struct sim_servo *v, uint32_t now)
{
    uint32_t due = v->servo.link.due_us;
    if (v->servo.link.state == LINK_WAITING && (int32_t)(due - v->hal.now_us) > 0 &&
        (int32_t)(now - due) > 0) {
        v->hal.now_us = due;
        servo_run_once(v);
    }
    v->hal.now_us = now;
    for (int i = 0; i < 8; i++) {
        servo_run_once(v);
        const struct link *l = &v->servo.link;
        bool next_frame = l->state == LINK_IDLE && frame_rx_peek(&v->servo.rx);
        bool answer_due = l->state == LINK_WAITING && (int32_t)(now - l->due_us) >= 0;
        if (!next_frame && !answer_due)
            break; /* else go on at once: no answer waits for the next tick */
    }
}

/* Bring one servo up to now. On a loaded host this loop may wake late; the servo then
 * catches up in steps of SIM_TICK_US of its own clock, so its control loop still sees
 * the motor at its own pace (a jump would look like a stall or a current spike to the
 * firmware). Beyond SIM_CATCH_UP_US behind (the process was stopped) it jumps. */
static void sim_step(struct sim_servo *v, uint32_t now)
{
    if ((int32_t)(now - v->hal.now_us) > (int32_t)SIM_CATCH_UP_US)
        v->hal.now_us = now - SIM_CATCH_UP_US;
    while ((int32_t)(now - v->hal.now_us) > (int32_t)SIM_TICK_US)
        servo_run_at(v, v->hal.now_us + SIM_TICK_US);
    servo_run_at(v, now);
    state_sync(v); /* also catches flash work done outside the wrapped calls */
}

/* A new servo (blank flash) gets its command-line ID the way a factory would configure
 * it: a WRITE of register 3 over the bus, in virtual time before the real clock starts.
 * So the persistent store saves it like any setting, and a restarted bus remembers a
 * later change of ID rather than the command line. The answer is discarded. */
static void servo_configure_id(struct sim_servo *v)
{
    uint8_t pkt[8];
    uint8_t params[2] = {REG_ID, v->id};
    uint16_t n = proto_build_packet(pkt, v->servo.link.id, INS_WRITE, params, 2);
    v->hal.now_us = 0;
    for (uint16_t i = 0; i < n; i++)
        servo_rx_isr(&v->servo, pkt[i]);
    for (uint32_t t = 0; t < SIM_CONFIG_US / 2u; t += 100u) {
        sim_step(v, t);
        if (v->servo.link.state == LINK_IDLE && v->servo.link.id == v->id)
            break;
    }
    if (v->servo.link.id != v->id)
        die(1, "could not set the ID of servo %u:%s", v->id, v->board->name);
    v->log_seen = v->hal.log_len;
}

static void servo_add(uint8_t id, const struct board *b, const char *state_dir)
{
    struct sim_servo *v = calloc(1, sizeof *v);
    if (!v)
        die(1, "out of memory");
    v->id = id;
    v->board = b;
    v->state_fd = -1;
    servos[servo_count++] = v;
    hal_host_init(&v->hal);
    hal_host_attach_board(&v->hal, b); /* the motor and switches of this board */
    if (state_dir)
        state_open(v, state_dir); /* before servo_init: the store reads the flash there */
    bool blank = pages_blank(v, 0, HAL_PAGES_ALL);
    if (pages_blank(v, HAL_PAGE_APP, 1))
        factory_program(v);
    servo_power_on(&v->servo, b, &v->hal); /* the bootloader's decision, then the firmware */
    if (blank && v->servo.link.id != id)
        servo_configure_id(v);
    state_sync(v);
}

static void servos_free(void)
{
    for (unsigned i = 0; i < servo_count; i++) {
        struct sim_servo *v = servos[i];
        if (v->state_fd >= 0)
            close(v->state_fd);
        free(v->state_path);
        free(v);
    }
    servo_count = 0;
}

/* ---- Client output --------------------------------------------------------------- */

/* Queue (or, with no client, drop) every servo byte whose stop bit has ended by now,
 * oldest first across servos. */
static void collect_tx(uint32_t now, bool client)
{
    for (;;) {
        struct sim_servo *next = 0;
        uint32_t next_end = 0;
        for (unsigned i = 0; i < servo_count; i++) {
            struct sim_servo *v = servos[i];
            if (v->log_seen == v->hal.log_len)
                continue;
            uint32_t end = hal_host_tx(&v->hal, v->log_seen)->end_us;
            if ((int32_t)(end - now) > 0)
                continue;
            if (!next || (int32_t)(end - next_end) < 0) {
                next = v;
                next_end = end;
            }
        }
        if (!next)
            return;
        uint8_t byte = hal_host_tx(&next->hal, next->log_seen++)->byte;
        if (client && out_len < SIM_OUT_MAX)
            out_buf[out_len++] = byte;
    }
}

/* Send what the client will take now. Returns false if the connection is gone. */
static bool flush_out(int fd)
{
    while (out_len) {
        ssize_t n = send(fd, out_buf, out_len, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n < 0)
            return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
        memmove(out_buf, out_buf + n, out_len - (size_t)n);
        out_len -= (size_t)n;
    }
    return true;
}

/* Microseconds until something is due: a tx byte's end, an answer's start or end. */
static uint32_t next_wake(uint32_t now)
{
    uint32_t wake = SIM_TICK_US;
    for (unsigned i = 0; i < servo_count; i++) {
        struct sim_servo *v = servos[i];
        int32_t d;
        if (v->log_seen != v->hal.log_len) {
            d = (int32_t)(hal_host_tx(&v->hal, v->log_seen)->end_us - now);
            if (d <= 0)
                return 0; /* a byte is ready to go out */
            wake = (uint32_t)d < wake ? (uint32_t)d : wake;
        }
        if (v->servo.link.state == LINK_WAITING) {
            d = (int32_t)(v->servo.link.due_us - now);
            wake = d > 0 && (uint32_t)d < wake ? (uint32_t)d : wake;
        }
    }
    return wake;
}

/* ---- Command line ---------------------------------------------------------------- */

static bool parse_uint(const char *s, unsigned long max, unsigned long *out)
{
    if (!*s || strlen(s) > 9u)
        return false;
    for (const char *p = s; *p; p++)
        if (*p < '0' || *p > '9')
            return false;
    *out = strtoul(s, 0, 10);
    return *out <= max;
}

static void parse_listen(const char *arg, struct sockaddr_in *sa)
{
    const char *colon = strrchr(arg, ':');
    char host[64];
    unsigned long port;
    if (!colon || (size_t)(colon - arg) >= sizeof host || colon == arg ||
        !parse_uint(colon + 1, 65535, &port))
        die(2, "bad --listen '%s': expected HOST:PORT, e.g. 127.0.0.1:4242", arg);
    memcpy(host, arg, (size_t)(colon - arg));
    host[colon - arg] = 0;
    memset(sa, 0, sizeof *sa);
    sa->sin_family = AF_INET;
    sa->sin_port = htons((uint16_t)port);
    if (strcmp(host, "localhost") == 0)
        strcpy(host, "127.0.0.1");
    if (inet_pton(AF_INET, host, &sa->sin_addr) != 1)
        die(2, "bad --listen '%s': '%s' is not an IPv4 address (e.g. 127.0.0.1)", arg, host);
}

struct servo_arg {
    uint8_t id;
    const struct board *board;
    const char *text;
};

static void parse_servo(const char *arg, struct servo_arg *out)
{
    const char *colon = strchr(arg, ':');
    char idtext[16];
    unsigned long id;
    if (!colon || (size_t)(colon - arg) >= sizeof idtext)
        die(2, "bad --servo '%s': expected ID:VARIANT, e.g. 1:arm", arg);
    memcpy(idtext, arg, (size_t)(colon - arg));
    idtext[colon - arg] = 0;
    if (!parse_uint(idtext, PROTO_ID_MAX, &id))
        die(2, "bad ID '%s' in --servo %s: IDs are 0-253", idtext, arg);
    const struct board *b = board_find(colon + 1);
    if (!b)
        die(2, "bad variant '%s' in --servo %s: expected base, foot, arm, wrist or finger",
            colon + 1, arg);
    out->id = (uint8_t)id;
    out->board = b;
    out->text = arg;
}

/* The value of option argv[*i] ("--opt VALUE" or "--opt=VALUE"), or 0 if it is not opt. */
static const char *option(int argc, char **argv, int *i, const char *opt)
{
    size_t n = strlen(opt);
    if (strncmp(argv[*i], opt, n) != 0)
        return 0;
    if (argv[*i][n] == '=')
        return argv[*i] + n + 1;
    if (argv[*i][n])
        return 0;
    if (*i + 1 >= argc)
        die(2, "%s needs a value (%s)", opt, usage);
    return argv[++*i];
}

/* ---- Main loop ------------------------------------------------------------------- */

static int listen_on(const struct sockaddr_in *sa, const char *text)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0)
        die(2, "cannot create a socket: %s", strerror(errno));
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one); /* restart after TIME_WAIT */
    if (bind(fd, (const struct sockaddr *)sa, sizeof *sa) != 0) {
        if (errno == EADDRINUSE)
            die(2, "cannot listen on %s: port in use (another servo-sim?)", text);
        die(2, "cannot listen on %s: %s", text, strerror(errno));
    }
    if (listen(fd, 1) != 0)
        die(2, "cannot listen on %s: %s", text, strerror(errno));
    return fd;
}

static void client_close(int *client)
{
    close(*client);
    *client = -1;
    out_len = 0;
}

/* Feed what the client sent to every servo, as it arrives; all of it if drain (else one
 * read); close the client at its end of stream. */
static void client_input(int *client, uint32_t now, bool drain)
{
    do {
        uint8_t in[4096];
        ssize_t n = recv(*client, in, sizeof in, MSG_DONTWAIT);
        if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
            client_close(client);
            return;
        }
        if (n < 0)
            return;
        for (unsigned i = 0; i < servo_count; i++) {
            struct sim_servo *v = servos[i];
            sim_step(v, now); /* bring the servo up to the arrival time */
            for (ssize_t k = 0; k < n; k++)
                servo_rx_isr(&v->servo, in[k]);
        }
    } while (drain);
}

int main(int argc, char **argv)
{
    struct sockaddr_in sa;
    const char *listen_text = 0, *state_dir = 0;
    static struct servo_arg args[SIM_SERVOS_MAX];
    unsigned nargs = 0;

    for (int i = 1; i < argc; i++) {
        const char *val;
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            printf("%s\n", usage);
            return 0;
        } else if ((val = option(argc, argv, &i, "--listen"))) {
            parse_listen(val, &sa);
            listen_text = val;
        } else if ((val = option(argc, argv, &i, "--servo"))) {
            struct servo_arg a;
            parse_servo(val, &a);
            for (unsigned k = 0; k < nargs; k++)
                if (args[k].id == a.id)
                    die(2, "duplicate ID %u: --servo %s and --servo %s", a.id, args[k].text,
                        a.text);
            args[nargs++] = a; /* distinct IDs 0-253: never more than SIM_SERVOS_MAX */
        } else if ((val = option(argc, argv, &i, "--state-dir"))) {
            if (!*val)
                die(2, "--state-dir needs a directory");
            state_dir = val;
        } else {
            die(2, "unknown option '%s' (%s)", argv[i], usage);
        }
    }
    if (!listen_text)
        die(2, "missing --listen HOST:PORT (%s)", usage);
    if (nargs == 0)
        args[nargs++] = (struct servo_arg){1, &board_arm, "1:arm"};
    if (state_dir && mkdir(state_dir, 0755) != 0 && errno != EEXIST)
        die(2, "cannot create --state-dir %s: %s", state_dir, strerror(errno));

    int lfd = listen_on(&sa, listen_text);
    socklen_t salen = sizeof sa;
    getsockname(lfd, (struct sockaddr *)&sa, &salen); /* the port chosen for port 0 */

    /* SIGINT/SIGTERM are blocked except inside ppoll(), so none is ever missed. */
    sigset_t block, during_poll;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    sigprocmask(SIG_BLOCK, &block, &during_poll);
    sigdelset(&during_poll, SIGINT);
    sigdelset(&during_poll, SIGTERM);
    struct sigaction act;
    memset(&act, 0, sizeof act);
    act.sa_handler = on_signal;
    sigaction(SIGINT, &act, 0);
    sigaction(SIGTERM, &act, 0);
    signal(SIGPIPE, SIG_IGN);

    clock_gettime(CLOCK_MONOTONIC, &clock_zero);
    for (unsigned i = 0; i < nargs; i++)
        servo_add(args[i].id, args[i].board, state_dir);
    uint32_t now = sim_now();
    for (unsigned i = 0; i < servo_count; i++)
        servos[i]->hal.now_us = now; /* the real clock starts after configuration */

    char addr[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &sa.sin_addr, addr, sizeof addr);
    printf("servo-sim: listening on %s:%u with", addr, (unsigned)ntohs(sa.sin_port));
    for (unsigned i = 0; i < servo_count; i++)
        printf(" %u:%s", servos[i]->id, servos[i]->board->name);
    printf("\n");
    fflush(stdout);

    int client = -1;
    while (!stop_signal) {
        now = sim_now();
        uint32_t wake = next_wake(now);
        struct timespec ts = {0, (long)wake * 1000};
        struct pollfd pfd[2] = {{lfd, POLLIN, 0}, {client, POLLIN, 0}};
        if (client >= 0 && out_len)
            pfd[1].events |= POLLOUT;
        int r = ppoll(pfd, client >= 0 ? 2u : 1u, &ts, &during_poll);
        if (r < 0 && errno != EINTR)
            die(1, "poll: %s", strerror(errno));
        if (stop_signal)
            break;
        now = sim_now();

        bool incoming = r > 0 && (pfd[0].revents & POLLIN);
        /* The client's input first (to its end, with a new client waiting), so a client
         * that closed and reconnected at once is not taken for a second client. */
        if (client >= 0 && ((r > 0 && (pfd[1].revents & (POLLIN | POLLHUP | POLLERR))) ||
                            incoming))
            client_input(&client, now, incoming);
        if (incoming) {
            int fd = accept4(lfd, 0, 0, SOCK_NONBLOCK | SOCK_CLOEXEC);
            if (fd >= 0 && client >= 0) {
                close(fd); /* one client at a time */
            } else if (fd >= 0) {
                int one = 1;
                setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
                client = fd;
            }
        }
        for (unsigned i = 0; i < servo_count; i++)
            sim_step(servos[i], now);
        collect_tx(now, client >= 0);
        if (client >= 0 && !flush_out(client))
            client_close(&client);
        if (client >= 0 && out_len == SIM_OUT_MAX) {
            fprintf(stderr, "servo-sim: client does not read its answers; closing it\n");
            client_close(&client);
        }
    }

    if (client >= 0)
        close(client);
    close(lfd);
    servos_free();
    return 0;
}
