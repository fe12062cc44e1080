/* args.c - servo-sim's command line (args.h). */
#include "args.h"

#include <arpa/inet.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"

static const char usage[] =
    "usage: servo-sim --listen HOST:PORT [--servo ID:VARIANT[:UID]]... "
    "[--uart HOST:PORT[:BAUD]]... [--state-dir DIR] "
    "[--report-commits] [--report-moves]";

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

static bool parse_uid(const char *s, uint8_t uid[HAL_UID_BYTES])
{
    if (strlen(s) != 2u * HAL_UID_BYTES)
        return false;
    for (unsigned i = 0; i < HAL_UID_BYTES; i++) {
        char pair[3] = {s[2u * i], s[2u * i + 1u], 0};
        char *end;
        if (pair[0] == '+' || pair[0] == '-' || pair[0] == ' ')
            return false;
        uid[i] = (uint8_t)strtoul(pair, &end, 16);
        if (*end)
            return false;
    }
    return true;
}

void args_default_uid(unsigned n, uint8_t uid[HAL_UID_BYTES])
{
    static const uint8_t rest[HAL_UID_BYTES - 4u] = {0x10, 0x00, 0x07, 'S', 'E', 'R', 'V', 'O'};
    uint32_t x = (uint32_t)n + 1u; /* MurmurHash3's finalizer: every bit mixed */
    x ^= x >> 16;
    x *= 0x85EBCA6Bu;
    x ^= x >> 13;
    x *= 0xC2B2AE35u;
    x ^= x >> 16;
    for (unsigned i = 0; i < 4u; i++)
        uid[i] = (uint8_t)(x >> (8u * i));
    memcpy(&uid[4], rest, sizeof rest);
}

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
    char variant[16];
    const char *uid = strchr(colon + 1, ':');
    size_t vlen = uid ? (size_t)(uid - colon - 1) : strlen(colon + 1);
    if (vlen >= sizeof variant)
        vlen = sizeof variant - 1u; /* too long for any variant: refused below */
    memcpy(variant, colon + 1, vlen);
    variant[vlen] = 0;
    const struct board *b = board_find(variant);
    if (!b)
        die(2, "bad variant '%s' in --servo %s: expected base, foot, arm, wrist or finger",
            variant, arg);
    out->uid_given = uid != 0;
    if (uid && !parse_uid(uid + 1, out->uid))
        die(2, "bad UID '%s' in --servo %s: expected 24 hex digits", uid + 1, arg);
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

static void add_servo(struct sim_args *a, const char *text)
{
    struct servo_arg s;
    if (a->nservos >= SIM_SERVOS_MAX)
        die(2, "too many --servo: at most %u", SIM_SERVOS_MAX);
    parse_servo(text, &s);
    if (!s.uid_given)
        args_default_uid(a->nservos, s.uid);
    for (unsigned k = 0; k < a->nservos; k++)
        if (memcmp(a->servo[k].uid, s.uid, HAL_UID_BYTES) == 0)
            die(2, "duplicate UID: --servo %s and --servo %s", a->servo[k].text, s.text);
    a->servo[a->nservos++] = s; /* one ID may repeat (factory-fresh servos): issue 27 */
}

/* --uart HOST:PORT[:BAUD] */
static void add_uart(struct sim_args *a, const char *text)
{
    char addr[80];
    unsigned long baud = 9600;
    if (a->nuarts >= sizeof a->uart / sizeof a->uart[0])
        die(2, "too many --uart: at most %zu", sizeof a->uart / sizeof a->uart[0]);
    if (strlen(text) >= sizeof addr)
        die(2, "bad --uart '%s': expected HOST:PORT[:BAUD]", text);
    strcpy(addr, text);
    char *first = strchr(addr, ':'), *last = strrchr(addr, ':');
    if (first && last != first) {
        *last = 0;
        if (!parse_uint(last + 1, 4000000, &baud) || baud < 1200)
            die(2, "bad baud in --uart '%s'", text);
    }
    parse_listen(addr, &a->uart[a->nuarts]);
    a->uart_baud[a->nuarts] = (uint32_t)baud;
    a->uart_text[a->nuarts++] = text;
}

void args_parse(int argc, char **argv, struct sim_args *a)
{
    memset(a, 0, sizeof *a);
    for (int i = 1; i < argc; i++) {
        const char *val;
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            printf("%s\n", usage);
            exit(0);
        } else if ((val = option(argc, argv, &i, "--listen"))) {
            parse_listen(val, &a->listen);
            a->listen_text = val;
        } else if ((val = option(argc, argv, &i, "--servo"))) {
            add_servo(a, val);
        } else if ((val = option(argc, argv, &i, "--uart"))) {
            add_uart(a, val);
        } else if (strcmp(argv[i], "--report-commits") == 0) {
            a->report_commits = true;
        } else if (strcmp(argv[i], "--report-moves") == 0) {
            a->report_moves = true;
        } else if ((val = option(argc, argv, &i, "--state-dir"))) {
            if (!*val)
                die(2, "--state-dir needs a directory");
            a->state_dir = val;
        } else {
            die(2, "unknown option '%s' (%s)", argv[i], usage);
        }
    }
    if (!a->listen_text)
        die(2, "missing --listen HOST:PORT (%s)", usage);
    if (a->nservos == 0) {
        a->servo[a->nservos] = (struct servo_arg){1, &board_arm, "1:arm", false, {0}};
        args_default_uid(0, a->servo[a->nservos++].uid);
    }
}
