/* client.c - servo-sim's TCP side (client.h). */
#include "client.h"

#include <errno.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "bus.h"
#include "rfc2217.h"
#include "sim.h"

#define OUT_MAX (1u << 20) /* bytes queued for a client that does not read */
#define IN_MAX 4096u

enum kind { KIND_UNKNOWN, KIND_RAW, KIND_RFC2217 };

static uint8_t out_buf[OUT_MAX];
static size_t out_len;
static enum kind kind;
static uint8_t first[2]; /* a client's first bytes while its kind is not known */
static size_t first_len;
static struct rfc2217 telnet;

int client_listen(struct sockaddr_in *sa, const char *text)
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
    if (listen(fd, SOMAXCONN) != 0)
        die(2, "cannot listen on %s: %s", text, strerror(errno));
    socklen_t len = sizeof *sa;
    getsockname(fd, (struct sockaddr *)sa, &len); /* the port chosen for port 0 */
    return fd;
}

static void client_close(int *client, int64_t now)
{
    close(*client);
    *client = -1;
    out_len = 0;
    bus_host_disconnect(now);
}

/* Queue bytes for the client (a client that does not read is closed in the loop). */
static void out_put(const uint8_t *p, size_t n)
{
    if (n > OUT_MAX - out_len)
        n = OUT_MAX - out_len;
    memcpy(out_buf + out_len, p, n);
    out_len += n;
}

/* Bytes of a Telnet client: data to the bus, negotiation answered, settings applied in
 * stream order (data sent before a baud change goes out at the old baud). */
static void telnet_input(const uint8_t *in, size_t n, int64_t now)
{
    static uint8_t data[IN_MAX], reply[RFC2217_REPLY_MAX(IN_MAX)];
    while (n) {
        size_t nd, reply_len = 0;
        size_t used = rfc2217_input(&telnet, in, n, data, &nd, reply, &reply_len);
        in += used;
        n -= used;
        out_put(reply, reply_len);
        if (nd)
            bus_host_send(data, nd, now);
        if (telnet.purge & RFC2217_PURGE_TX)
            bus_host_purge(now);
        if (telnet.purge & RFC2217_PURGE_RX)
            (void)bus_output(0, 0);
        telnet.purge = 0;
        if (telnet.baud_changed) {
            bus_host_uart(telnet.baud);
            telnet.baud_changed = false;
        }
    }
}

/* A client's bytes, in chunks of at most IN_MAX: its kind first, once. */
static void host_input(const uint8_t *in, size_t n, int64_t now)
{
    if (kind == KIND_UNKNOWN) {
        while (first_len < sizeof first && n) {
            first[first_len++] = *in++;
            n--;
        }
        int telnet_client = rfc2217_detect(first, first_len);
        if (telnet_client < 0)
            return; /* a lone IAC: wait for the next byte */
        kind = telnet_client ? KIND_RFC2217 : KIND_RAW;
        if (kind == KIND_RFC2217) {
            uint8_t reply[64];
            size_t len = rfc2217_start(&telnet, reply);
            out_put(reply, len);
            bus_host_uart(telnet.baud);
        }
        host_input(first, first_len, now);
    }
    if (kind == KIND_RAW)
        bus_host_raw(in, n, now);
    else if (n)
        telnet_input(in, n, now);
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

/* Room for one more read of a client: a raw client's bytes wait for the servos' UARTs
 * (bus.h), and a client faster than them waits in the socket (TCP's flow control). */
static bool room_for_input(void)
{
    return kind != KIND_RAW || bus_host_raw_room() >= IN_MAX;
}

/* Feed what the client sent to the bus, as it arrives; all of it if drain (else one
 * read), as far as there is room; close the client at its end of stream. */
static void client_input(int *client, int64_t now, bool drain)
{
    do {
        if (!room_for_input())
            return; /* the rest waits in the socket */
        uint8_t in[IN_MAX];
        ssize_t n = recv(*client, in, sizeof in, MSG_DONTWAIT);
        if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
            client_close(client, now);
            return;
        }
        if (n < 0)
            return;
        host_input(in, (size_t)n, now);
    } while (drain);
}

static void client_accept(int lfd, int *client, int64_t now)
{
    int fd = accept4(lfd, 0, 0, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd >= 0 && *client >= 0) {
        close(fd); /* one client at a time */
    } else if (fd >= 0) {
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        *client = fd;
        kind = KIND_UNKNOWN;
        first_len = 0;
        bus_host_connect(now);
    }
}

/* What the host heard, to the client as its kind needs it. */
static void client_output(bool connected)
{
    static uint8_t heard[65536], escaped[2u * sizeof heard];
    size_t n = bus_output(heard, connected && kind != KIND_UNKNOWN ? sizeof heard : 0);
    if (kind == KIND_RFC2217)
        out_put(escaped, rfc2217_escape(heard, n, escaped));
    else
        out_put(heard, n);
}

/* External UARTs (bus.h bus_add_ext): what each sent onto the line, what it heard. */
static void ext_io(const struct pollfd *pfd, int64_t now)
{
    uint8_t buf[4096];
    for (unsigned e = 0; e < bus_ext_count(); e++) {
        if (!(pfd[e].revents & (POLLIN | POLLHUP | POLLERR)))
            continue;
        ssize_t n = read(bus_ext_fd(e), buf, sizeof buf);
        if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR))
            die(1, "--uart %u: the device closed its connection", e + 1u);
        if (n > 0)
            bus_ext_send(e, buf, (size_t)n, now);
    }
}

static void ext_output(void)
{
    uint8_t buf[4096];
    for (unsigned e = 0; e < bus_ext_count(); e++) {
        size_t n;
        while ((n = bus_ext_output(e, buf, sizeof buf)) > 0)
            for (size_t at = 0; at < n;) {
                ssize_t w = write(bus_ext_fd(e), buf + at, n - at);
                if (w < 0 && errno != EINTR)
                    die(1, "--uart %u: %s", e + 1u, strerror(errno));
                at += w > 0 ? (size_t)w : 0u;
            }
    }
}

void client_serve(int lfd, const sigset_t *poll_mask, volatile sig_atomic_t *stop)
{
    int client = -1;
    while (!*stop) {
        int64_t now = bus_now();
        uint32_t wake = bus_next_wake(now);
        struct timespec ts = {0, (long)wake * 1000};
        struct pollfd pfd[2u + BUS_EXT_MAX] = {{lfd, POLLIN, 0},
                                               {client, room_for_input() ? POLLIN : 0, 0}};
        if (client >= 0 && out_len)
            pfd[1].events |= POLLOUT;
        for (unsigned e = 0; e < bus_ext_count(); e++)
            pfd[2u + e] = (struct pollfd){bus_ext_fd(e), POLLIN, 0};
        int r = ppoll(pfd, 2u + bus_ext_count(), &ts, poll_mask);
        if (r < 0 && errno != EINTR)
            die(1, "poll: %s", strerror(errno));
        if (*stop)
            break;
        now = bus_now();

        bool incoming = r > 0 && (pfd[0].revents & POLLIN);
        /* The client's input first (to its end, with a new client waiting), so a client
         * that closed and reconnected at once is not taken for a second client. */
        if (client >= 0 && ((r > 0 && (pfd[1].revents & (POLLIN | POLLHUP | POLLERR))) ||
                            incoming))
            client_input(&client, now, incoming);
        if (incoming)
            client_accept(lfd, &client, now);
        if (r > 0)
            ext_io(&pfd[2], now);
        bus_advance(now);
        ext_output();
        client_output(client >= 0);
        if (client >= 0 && !flush_out(client))
            client_close(&client, now);
        if (client >= 0 && out_len == OUT_MAX) {
            fprintf(stderr, "servo-sim: client does not read its answers; closing it\n");
            client_close(&client, now);
        }
    }
    if (client >= 0)
        close(client);
}
