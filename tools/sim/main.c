/* main.c - servo-sim: the virtual servo bus in real time (sim.h names its parts).
 *
 *   servo-sim --listen HOST:PORT [--servo ID:VARIANT]... [--state-dir DIR]
 *
 * The bus model is documented in bus.h and tools/python/README.md. SIGINT/SIGTERM end it
 * cleanly. Exit status: 0 after a signal, 2 for a bad command line or a port that cannot
 * be listened on, 1 for a failure while running. */
#include <arpa/inet.h>
#include <netinet/tcp.h>
#include <errno.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "args.h"
#include "bus.h"
#include "client.h"
#include "sim.h"

static volatile sig_atomic_t stop_signal;

void die(int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fputs("servo-sim: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    exit(code);
}

static void on_signal(int sig)
{
    stop_signal = sig;
}

/* SIGINT/SIGTERM are blocked except inside the poll (poll_mask), so none is ever missed;
 * a client that went away is not a signal. */
static void signals_setup(sigset_t *poll_mask)
{
    sigset_t block;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    sigprocmask(SIG_BLOCK, &block, poll_mask);
    sigdelset(poll_mask, SIGINT);
    sigdelset(poll_mask, SIGTERM);
    struct sigaction act;
    memset(&act, 0, sizeof act);
    act.sa_handler = on_signal;
    sigaction(SIGINT, &act, 0);
    sigaction(SIGTERM, &act, 0);
    signal(SIGPIPE, SIG_IGN);
}

/* The first line on stdout, which scripts wait for: the address and the servos. */
static void banner(const struct sockaddr_in *sa)
{
    char addr[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &sa->sin_addr, addr, sizeof addr);
    printf("servo-sim: listening on %s:%u with", addr, (unsigned)ntohs(sa->sin_port));
    for (unsigned i = 0; i < bus_count(); i++)
        printf(" %u:%s", bus_servo(i)->arg_id, bus_servo(i)->node.board->name);
    printf("\n");
    fflush(stdout);
}

/* Connect to a --uart device (an emulator may still be starting: up to 10 s). */
static int uart_connect(const struct sockaddr_in *sa, const char *text)
{
    for (int tries = 0; tries < 100; tries++) {
        int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd < 0)
            die(1, "socket: %s", strerror(errno));
        if (connect(fd, (const struct sockaddr *)sa, sizeof *sa) == 0) {
            int one = 1;
            setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
            return fd;
        }
        close(fd);
        struct timespec ts = {0, 100000000L};
        nanosleep(&ts, 0);
    }
    die(2, "--uart %s: cannot connect: %s", text, strerror(errno));
}

int main(int argc, char **argv)
{
    static struct sim_args args;
    args_parse(argc, argv, &args);
    if (args.state_dir && mkdir(args.state_dir, 0755) != 0 && errno != EEXIST)
        die(2, "cannot create --state-dir %s: %s", args.state_dir, strerror(errno));
    int lfd = client_listen(&args.listen, args.listen_text);
    sigset_t poll_mask;
    signals_setup(&poll_mask);
    for (unsigned i = 0; i < args.nservos; i++) {
        const struct servo_arg *v = &args.servo[i];
        bool shared = v->uid_given; /* one ID and variant twice: the files need the UID */
        for (unsigned k = 0; k < args.nservos; k++)
            shared |= k != i && args.servo[k].id == v->id && args.servo[k].board == v->board;
        bus_add(v->id, v->board, v->uid, shared, args.state_dir);
    }
    for (unsigned u = 0; u < args.nuarts; u++)
        bus_add_ext(uart_connect(&args.uart[u], args.uart_text[u]), args.uart_baud[u]);
    bus_start();
    if (args.report_commits)
        bus_report_commits();
    if (args.report_moves)
        bus_report_moves();
    banner(&args.listen);
    client_serve(lfd, &poll_mask, &stop_signal);
    close(lfd);
    bus_free();
    return 0;
}
