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
#include "sim.h"

#define OUT_MAX (1u << 20) /* bytes queued for a client that does not read */

static uint8_t out_buf[OUT_MAX];
static size_t out_len;

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
    if (listen(fd, 1) != 0)
        die(2, "cannot listen on %s: %s", text, strerror(errno));
    socklen_t len = sizeof *sa;
    getsockname(fd, (struct sockaddr *)sa, &len); /* the port chosen for port 0 */
    return fd;
}

static void client_close(int *client)
{
    close(*client);
    *client = -1;
    out_len = 0;
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

/* Feed what the client sent to the servos, as it arrives; all of it if drain (else one
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
        bus_host_bytes(in, (size_t)n, now);
    } while (drain);
}

static void client_accept(int lfd, int *client)
{
    int fd = accept4(lfd, 0, 0, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd >= 0 && *client >= 0) {
        close(fd); /* one client at a time */
    } else if (fd >= 0) {
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        *client = fd;
    }
}

void client_serve(int lfd, const sigset_t *poll_mask, volatile sig_atomic_t *stop)
{
    int client = -1;
    while (!*stop) {
        uint32_t now = bus_now();
        uint32_t wake = bus_next_wake(now);
        struct timespec ts = {0, (long)wake * 1000};
        struct pollfd pfd[2] = {{lfd, POLLIN, 0}, {client, POLLIN, 0}};
        if (client >= 0 && out_len)
            pfd[1].events |= POLLOUT;
        int r = ppoll(pfd, client >= 0 ? 2u : 1u, &ts, poll_mask);
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
            client_accept(lfd, &client);
        bus_step(now);
        out_len += bus_output(now, out_buf + out_len, client >= 0 ? OUT_MAX - out_len : 0);
        if (client >= 0 && !flush_out(client))
            client_close(&client);
        if (client >= 0 && out_len == OUT_MAX) {
            fprintf(stderr, "servo-sim: client does not read its answers; closing it\n");
            client_close(&client);
        }
    }
    if (client >= 0)
        close(client);
}
