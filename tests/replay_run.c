/* replay_run.c - runs one replay transcript (tests/replay/README.md) against host-built
 * servos on the virtual bus, through the real receive-interrupt entry point and main
 * loop, in virtual time. Exit 0 when every line holds. */
#include <ctype.h>
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "vbus.h"

#define LINE_MAX_BYTES 2048
#define EXPECT_TIMEOUT_US 5000000u

static const char *path;
static int lineno;
static uint8_t node_name[VBUS_NODES_MAX]; /* the ID each servo was declared with */

static void fail(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s:%d: ", path, lineno);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    exit(1);
}

static long number(const char *tok, int base)
{
    char *end;
    errno = 0;
    long v = strtol(tok, &end, base);
    if (!tok[0] || *end || errno)
        fail("not a number: '%s'", tok);
    return v;
}

/* Parse hex bytes; "CHK" stands for the 8-bit sum of the bytes after the header so far;
 * "+N" (send only) records a gap of N us before the next byte. */
static int parse_bytes(char **tok, int ntok, uint8_t *out, uint32_t *gap_before)
{
    int n = 0;
    uint32_t gap = 0;
    for (int i = 0; i < ntok; i++) {
        if (tok[i][0] == '+') {
            if (!gap_before)
                fail("gaps are only allowed in send");
            gap = (uint32_t)number(tok[i] + 1, 10);
            continue;
        }
        if (n >= LINE_MAX_BYTES)
            fail("too many bytes on one line");
        if (gap_before)
            gap_before[n] = gap;
        gap = 0;
        if (strcmp(tok[i], "CHK") == 0)
            out[n] = n > 2 ? proto_sum(&out[2], (uint16_t)(n - 2)) : 0;
        else if (strlen(tok[i]) == 2 && isxdigit((unsigned char)tok[i][0]) &&
                 isxdigit((unsigned char)tok[i][1]))
            out[n] = (uint8_t)number(tok[i], 16);
        else
            fail("not a hex byte: '%s'", tok[i]);
        n++;
    }
    return n;
}

static struct node *node_by_name(struct vbus *b, const char *tok)
{
    long id = number(tok, 10);
    for (uint8_t i = 0; i < b->nodes; i++)
        if (node_name[i] == id)
            return &b->node[i];
    fail("no servo declared with ID %ld", id);
    return 0;
}

static void dump(const char *what, const uint8_t *p, int n)
{
    fprintf(stderr, "  %s:", what);
    for (int i = 0; i < n; i++)
        fprintf(stderr, " %02X", p[i]);
    fputc('\n', stderr);
}

static void do_send(struct vbus *b, char **tok, int ntok)
{
    static uint8_t bytes[LINE_MAX_BYTES];
    static uint32_t gaps[LINE_MAX_BYTES];
    int n = parse_bytes(tok, ntok, bytes, gaps);
    int start = 0;
    for (int i = 1; i <= n; i++) {
        if (i == n || gaps[i]) {
            vbus_host_send(b, &bytes[start], (uint32_t)(i - start));
            if (i < n)
                vbus_run_until(b, b->now_us + gaps[i]);
            start = i;
        }
    }
}

static void do_expect(struct vbus *b, char **tok, int ntok)
{
    static uint8_t want[LINE_MAX_BYTES], got[LINE_MAX_BYTES];
    int at = -1;
    for (int i = 0; i < ntok; i++)
        if (strcmp(tok[i], "at") == 0)
            at = i;
    if (at >= 0 && at + 3 != ntok)
        fail("expect ... at MIN MAX");
    int n = parse_bytes(tok, at >= 0 ? at : ntok, want, 0);
    uint32_t deadline = b->now_us + EXPECT_TIMEOUT_US;
    while (vbus_host_pending(b) < (uint32_t)n && (int32_t)(deadline - b->now_us) > 0)
        vbus_run_until(b, b->now_us + 100u);
    uint32_t have = vbus_host_pending(b);
    int m = have < (uint32_t)n ? (int)have : n;
    uint32_t first_start = 0, last_end = b->now_us;
    for (int i = 0; i < m; i++) {
        const struct vbus_byte *w = vbus_host_next(b);
        if (w->baud != b->host_baud)
            fail("servo byte %d sent at %u baud, the host listens at %u", i, w->baud,
                 b->host_baud);
        got[i] = w->byte;
        if (i == 0)
            first_start = w->start_us;
        last_end = w->end_us;
    }
    if (m < n || memcmp(want, got, (size_t)n) != 0) {
        fprintf(stderr, "%s:%d: answer differs\n", path, lineno);
        dump("expected", want, n);
        dump("received", got, m);
        exit(1);
    }
    if ((int32_t)(last_end - b->now_us) > 0)
        vbus_run_until(b, last_end); /* the host waits for the whole answer */
    if (at >= 0) {
        long lo = number(tok[at + 1], 10), hi = number(tok[at + 2], 10);
        long t = (long)(int32_t)(first_start - b->last_host_end_us);
        if (t < lo || t > hi)
            fail("answer started %ld us after the request, expected %ld..%ld", t, lo, hi);
    }
}

static void do_silence(struct vbus *b, long us)
{
    vbus_run_until(b, b->now_us + (uint32_t)us);
    if (vbus_host_pending(b)) {
        const struct vbus_byte *w = vbus_host_next(b);
        fail("expected silence, servo sent %02X at t=%u us (%u baud)", w->byte, w->start_us,
             w->baud);
    }
}

static void do_reg(struct vbus *b, char **tok, int ntok)
{
    if (ntok < 4 || strcmp(tok[2], "="))
        fail("reg ID ADDR = HEX...");
    struct node *n = node_by_name(b, tok[0]);
    long addr = number(tok[1], 10);
    static uint8_t want[LINE_MAX_BYTES];
    int cnt = parse_bytes(&tok[3], ntok - 3, want, 0);
    if (addr < 0 || addr + cnt > (long)REGS_SIZE)
        fail("register range outside the table");
    if (memcmp(&n->servo.regs.mem[addr], want, (size_t)cnt) != 0) {
        fprintf(stderr, "%s:%d: register %ld differs\n", path, lineno, addr);
        dump("expected", want, cnt);
        dump("in table", &n->servo.regs.mem[addr], cnt);
        exit(1);
    }
}

static void run_line(struct vbus *b, char **tok, int ntok)
{
    const char *cmd = tok[0];
    tok++;
    ntok--;
    if (strcmp(cmd, "servo") == 0) {
        if (ntok != 2 && ntok != 3)
            fail("servo ID VARIANT [UID]");
        const struct board *bd = board_find(tok[1]);
        if (!bd)
            fail("unknown variant '%s'", tok[1]);
        if (b->nodes == VBUS_NODES_MAX)
            fail("too many servos");
        long id = number(tok[0], 10);
        if (b->nodes == 0)
            b->host_baud = bd->default_baud;
        node_name[b->nodes] = (uint8_t)id;
        struct hal *h = &b->node[vbus_add(b, bd, (uint8_t)id)].hal;
        if (ntok == 3) { /* hal_uid(): 24 hex digits, byte 0 first */
            if (strlen(tok[2]) != 2u * HAL_UID_BYTES)
                fail("a UID is 24 hex digits");
            for (unsigned i = 0; i < HAL_UID_BYTES; i++) {
                char pair[3] = {tok[2][2u * i], tok[2][2u * i + 1u], 0};
                h->uid[i] = (uint8_t)number(pair, 16);
            }
        }
    } else if (!b->nodes) {
        fail("declare a servo first");
    } else if (strcmp(cmd, "host-baud") == 0 && ntok == 1) {
        b->host_baud = (uint32_t)number(tok[0], 10);
    } else if (strcmp(cmd, "step") == 0 && ntok == 1) {
        b->step_us = (uint32_t)number(tok[0], 10);
    } else if (strcmp(cmd, "send") == 0 && ntok >= 1) {
        do_send(b, tok, ntok);
    } else if (strcmp(cmd, "expect") == 0 && ntok >= 1) {
        do_expect(b, tok, ntok);
    } else if (strcmp(cmd, "silence") == 0 && ntok == 1) {
        do_silence(b, number(tok[0], 10));
    } else if (strcmp(cmd, "wait") == 0 && ntok == 1) {
        vbus_run_until(b, b->now_us + (uint32_t)number(tok[0], 10));
    } else if (strcmp(cmd, "reg") == 0) {
        do_reg(b, tok, ntok);
    } else if (strcmp(cmd, "power-cycle") == 0 && ntok == 1) {
        vbus_power_cycle(b, (uint8_t)(node_by_name(b, tok[0]) - b->node));
    } else if (strcmp(cmd, "sensor") == 0 && ntok == 3) {
        struct hal *h = &node_by_name(b, tok[0])->hal;
        long v = number(tok[2], 10);
        if (strcmp(tok[1], "temperature") == 0)
            h->temperature_dc = (int16_t)v; /* 0.1 degree C */
        else if (strcmp(tok[1], "supply") == 0)
            h->supply_mv = (uint16_t)v;
        else if (strcmp(tok[1], "switches") == 0)
            h->photo = (uint8_t)v;
        else
            fail("sensor ID temperature|supply|switches VALUE");
    } else if (strcmp(cmd, "collisions") == 0 && ntok == 1) {
        if ((long)b->collisions != number(tok[0], 10))
            fail("%u collisions on the bus, expected %s", b->collisions, tok[0]);
    } else {
        fail("unknown or malformed line '%s'", cmd);
    }
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: replay_run TRANSCRIPT\n");
        return 2;
    }
    path = argv[1];
    FILE *f = fopen(path, "r");
    if (!f) {
        perror(path);
        return 2;
    }
    static struct vbus bus;
    vbus_init(&bus);
    static char line[16384];
    int lines_run = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *hash = strchr(line, '#');
        if (hash)
            *hash = 0;
        static char *tok[LINE_MAX_BYTES + 8];
        int ntok = 0;
        for (char *t = strtok(line, " \t\r\n"); t; t = strtok(0, " \t\r\n")) {
            if (ntok == LINE_MAX_BYTES + 8)
                fail("line too long");
            tok[ntok++] = t;
        }
        if (ntok) {
            run_line(&bus, tok, ntok);
            lines_run++;
        }
    }
    fclose(f);
    if (bus.collisions) {
        lineno = 0;
        fail("%u bus collisions", bus.collisions);
    }
    printf("%s: %d lines passed\n", path, lines_run);
    return 0;
}
