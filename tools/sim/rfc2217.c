/* rfc2217.c - the server side of Telnet COM-PORT-CONTROL (rfc2217.h). */
#include "rfc2217.h"

#include <string.h>

/* Telnet (RFC 854, 855) */
#define SE 240u
#define SB 250u
#define WILL 251u
#define WONT 252u
#define DO 253u
#define DONT 254u
#define OPT_BINARY 0u
#define OPT_SGA 3u
#define OPT_COM_PORT 44u

/* COM-PORT-OPTION commands (RFC 2217); the server answers command c with c + 100. */
#define SET_BAUDRATE 1u
#define SET_DATASIZE 2u
#define SET_PARITY 3u
#define SET_STOPSIZE 4u
#define SET_CONTROL 5u
#define NOTIFY_LINESTATE 6u
#define NOTIFY_MODEMSTATE 7u
#define SET_LINESTATE_MASK 10u
#define SET_MODEMSTATE_MASK 11u
#define PURGE_DATA 12u
#define SERVER 100u

#define MODEM_CD 0x80u
#define MODEM_DSR 0x20u
#define MODEM_CTS 0x10u

enum { S_DATA, S_IAC, S_VERB, S_SB, S_SB_IAC };

int rfc2217_detect(const uint8_t *in, size_t n)
{
    if (n == 0)
        return -1;
    if (in[0] != RFC2217_IAC)
        return 0;
    if (n == 1)
        return -1;
    return in[1] >= SB && in[1] <= DONT;
}

static bool bit(const uint8_t *set, uint8_t opt)
{
    return ((unsigned)set[opt / 8u] >> (opt % 8u)) & 1u;
}

static void set_bit(uint8_t *set, uint8_t opt, bool on)
{
    if (on)
        set[opt / 8u] = (uint8_t)(set[opt / 8u] | (1u << (opt % 8u)));
    else
        set[opt / 8u] = (uint8_t)(set[opt / 8u] & ~(1u << (opt % 8u)));
}

static bool supported(uint8_t opt)
{
    return opt == OPT_BINARY || opt == OPT_SGA || opt == OPT_COM_PORT;
}

static void put(uint8_t *reply, size_t *len, uint8_t b)
{
    reply[(*len)++] = b;
}

static void put_option(uint8_t *reply, size_t *len, uint8_t verb, uint8_t opt)
{
    put(reply, len, RFC2217_IAC);
    put(reply, len, verb);
    put(reply, len, opt);
}

size_t rfc2217_start(struct rfc2217 *t, uint8_t *reply)
{
    memset(t, 0, sizeof *t);
    t->baud = RFC2217_BAUD_DEFAULT;
    size_t len = 0;
    put_option(reply, &len, DO, OPT_BINARY);
    set_bit(t->asked_him, OPT_BINARY, true);
    put_option(reply, &len, WILL, OPT_BINARY);
    set_bit(t->asked_us, OPT_BINARY, true);
    return len;
}

/* WILL/WONT (the client's side of an option) and DO/DONT (ours), without loops: a
 * request is answered only when it changes the state, and an answer to our own request
 * is not answered again. */
static void negotiate(struct rfc2217 *t, uint8_t verb, uint8_t opt, uint8_t *reply, size_t *len)
{
    bool will = verb == WILL || verb == WONT;
    bool yes = verb == WILL || verb == DO;
    uint8_t *on = will ? t->him : t->us;
    uint8_t *asked = will ? t->asked_him : t->asked_us;
    bool was_asked = bit(asked, opt);
    set_bit(asked, opt, false);
    if (yes && !supported(opt)) {
        put_option(reply, len, will ? DONT : WONT, opt);
        return;
    }
    if (yes == bit(on, opt))
        return; /* no change: nothing to say */
    set_bit(on, opt, yes);
    if (!was_asked)
        put_option(reply, len, will ? (yes ? DO : DONT) : (yes ? WILL : WONT), opt);
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

/* IAC SB COM-PORT-OPTION (cmd + 100) value IAC SE, with IAC doubled in the value. */
static void answer(uint8_t *reply, size_t *len, uint8_t cmd, const uint8_t *value, size_t n)
{
    put(reply, len, RFC2217_IAC);
    put(reply, len, SB);
    put(reply, len, OPT_COM_PORT);
    put(reply, len, (uint8_t)(cmd + SERVER));
    for (size_t i = 0; i < n; i++) {
        put(reply, len, value[i]);
        if (value[i] == RFC2217_IAC)
            put(reply, len, RFC2217_IAC);
    }
    put(reply, len, RFC2217_IAC);
    put(reply, len, SE);
}

/* SET-CONTROL: what the port does after value (the answer). */
static uint8_t control(uint8_t value)
{
    switch (value) {
    case 7: /* ask DTR */
        return 8;
    case 8: case 9: case 11: case 12: /* DTR or RTS on/off: no such line on a bus */
        return value;
    case 10: /* ask RTS */
        return 11;
    case 4: case 5: case 6: /* BREAK: not modelled */
        return 6;
    case 13: case 14: case 15: case 16: /* inbound flow control: none */
        return 14;
    default: /* outbound flow control: none */
        return 1;
    }
}

static void com_port(struct rfc2217 *t, uint8_t *reply, size_t *len)
{
    if (t->sb_len < 2 || t->sb[0] != OPT_COM_PORT)
        return;
    uint8_t cmd = t->sb[1];
    const uint8_t *v = &t->sb[2];
    size_t n = t->sb_len - 2u;
    uint8_t out[4];
    switch (cmd) {
    case SET_BAUDRATE:
        if (n >= 4) {
            uint32_t baud = get32(v);
            if (baud >= RFC2217_BAUD_MIN && baud <= RFC2217_BAUD_MAX) {
                t->baud = baud;
                t->baud_changed = true;
            }
        }
        out[0] = (uint8_t)(t->baud >> 24);
        out[1] = (uint8_t)(t->baud >> 16);
        out[2] = (uint8_t)(t->baud >> 8);
        out[3] = (uint8_t)t->baud;
        answer(reply, len, cmd, out, 4);
        break;
    case SET_DATASIZE:
        out[0] = 8;
        answer(reply, len, cmd, out, 1);
        break;
    case SET_PARITY: /* none */
    case SET_STOPSIZE: /* one */
        out[0] = 1;
        answer(reply, len, cmd, out, 1);
        break;
    case SET_CONTROL:
        out[0] = control(n ? v[0] : 0);
        answer(reply, len, cmd, out, 1);
        break;
    case NOTIFY_LINESTATE:
        out[0] = 0;
        answer(reply, len, cmd, out, 1);
        break;
    case NOTIFY_MODEMSTATE:
        out[0] = MODEM_CD | MODEM_DSR | MODEM_CTS;
        answer(reply, len, cmd, out, 1);
        break;
    case SET_LINESTATE_MASK:
    case SET_MODEMSTATE_MASK:
        answer(reply, len, cmd, v, n ? 1u : 0u);
        break;
    case PURGE_DATA:
        if (n && v[0] >= 1 && v[0] <= 3)
            t->purge = (uint8_t)(t->purge | v[0]);
        answer(reply, len, cmd, v, n ? 1u : 0u);
        break;
    default: /* FLOWCONTROL-SUSPEND/RESUME, anything else: nothing to say */
        break;
    }
}

size_t rfc2217_input(struct rfc2217 *t, const uint8_t *in, size_t n, uint8_t *data,
                     size_t *ndata, uint8_t *reply, size_t *reply_len)
{
    size_t nd = 0, i;
    for (i = 0; i < n && !t->baud_changed && !t->purge; i++) {
        uint8_t b = in[i];
        switch (t->state) {
        case S_DATA:
            if (b == RFC2217_IAC)
                t->state = S_IAC;
            else
                data[nd++] = b;
            break;
        case S_IAC:
            if (b == RFC2217_IAC) {
                data[nd++] = b; /* a doubled IAC is one 0xFF of data */
                t->state = S_DATA;
            } else if (b >= WILL && b <= DONT) {
                t->verb = b;
                t->state = S_VERB;
            } else if (b == SB) {
                t->sb_len = 0;
                t->state = S_SB;
            } else {
                t->state = S_DATA; /* NOP, BREAK, AYT...: nothing to do on a servo bus */
            }
            break;
        case S_VERB:
            negotiate(t, t->verb, b, reply, reply_len);
            t->state = S_DATA;
            break;
        case S_SB:
            if (b == RFC2217_IAC)
                t->state = S_SB_IAC;
            else if (t->sb_len < sizeof t->sb)
                t->sb[t->sb_len++] = b;
            break;
        case S_SB_IAC:
            if (b == SE) {
                com_port(t, reply, reply_len);
                t->state = S_DATA;
            } else {
                if (t->sb_len < sizeof t->sb)
                    t->sb[t->sb_len++] = b; /* IAC IAC: one 0xFF */
                t->state = S_SB;
            }
            break;
        default:
            t->state = S_DATA;
            break;
        }
    }
    *ndata = nd;
    return i;
}

size_t rfc2217_escape(const uint8_t *in, size_t n, uint8_t *out)
{
    size_t len = 0;
    for (size_t i = 0; i < n; i++) {
        out[len++] = in[i];
        if (in[i] == RFC2217_IAC)
            out[len++] = RFC2217_IAC;
    }
    return len;
}
