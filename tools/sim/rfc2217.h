/* rfc2217.h - the server side of Telnet COM-PORT-CONTROL (RFC 2217), as pyserial's
 * rfc2217://HOST:PORT speaks it and ser2net serves it: option negotiation, the com port
 * commands, and the data stream with IAC (0xFF) doubled. Pure: bytes in, data bytes and
 * replies out; the caller applies what the client asked (baud, purge).
 *
 * Negotiated: BINARY, SUPPRESS-GO-AHEAD and COM-PORT-OPTION, both ways; ECHO and every
 * other option refused. Com port commands: SET-BAUDRATE (any baud from 50 to 4 Mbaud;
 * 0 asks for the present one), SET-DATASIZE/PARITY/STOPSIZE (the bus is 8N1: that is the
 * answer whatever is asked, so a client asking another framing sees it refused),
 * SET-CONTROL (no flow control; DTR and RTS accepted and without effect, there being no
 * such lines; BREAK refused), NOTIFY-MODEMSTATE (CTS, DSR and CD on), the state masks
 * (echoed), PURGE-DATA (reported to the caller). FLOWCONTROL-SUSPEND/RESUME are ignored
 * (answers are short; the caller's buffer takes them). */
#ifndef RFC2217_H
#define RFC2217_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define RFC2217_IAC 0xFFu
#define RFC2217_PURGE_RX 1u /* the client's receive buffer: bytes not yet sent to it */
#define RFC2217_PURGE_TX 2u /* its transmit buffer: bytes not yet on the line */
#define RFC2217_BAUD_DEFAULT 9600u
#define RFC2217_BAUD_MIN 50u
#define RFC2217_BAUD_MAX 4000000u

struct rfc2217 {
    uint8_t state; /* of the Telnet parser */
    uint8_t verb;  /* WILL, WONT, DO or DONT being read */
    uint8_t sb[24];
    uint8_t sb_len;
    uint8_t us[32], him[32], asked_us[32], asked_him[32]; /* one bit per option */
    uint32_t baud;     /* the client's: RFC2217_BAUD_DEFAULT until it sets one */
    bool baud_changed; /* set by a SET-BAUDRATE; the caller clears it */
    uint8_t purge;     /* RFC2217_PURGE_* asked; the caller clears it */
};

/* Is this the start of a Telnet client: IAC then WILL, WONT, DO, DONT or SB? 1 yes, 0 no
 * (a raw client), -1 not known yet (one byte, IAC). */
int rfc2217_detect(const uint8_t *in, size_t n);

/* Room for the replies to n input bytes. */
#define RFC2217_REPLY_MAX(n) (3u * (n) + 64u)

/* A new session; writes what the server asks first (BINARY both ways) to reply and
 * returns its length. */
size_t rfc2217_start(struct rfc2217 *t, uint8_t *reply);

/* Feed up to n bytes from the client. Data bytes go to data (*ndata of them, at most n);
 * replies are appended to reply at *reply_len (room: RFC2217_REPLY_MAX(n)). It stops
 * right after a command that changes the port (baud_changed or purge set), so the data
 * before it can be sent at the old settings: returns the bytes consumed. */
size_t rfc2217_input(struct rfc2217 *t, const uint8_t *in, size_t n, uint8_t *data,
                     size_t *ndata, uint8_t *reply, size_t *reply_len);

/* Data for the client with IAC doubled, into out (room: 2 n). Returns its length. */
size_t rfc2217_escape(const uint8_t *in, size_t n, uint8_t *out);

#endif
