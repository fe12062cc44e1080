/* client.h - servo-sim's TCP side: one listening socket (backlog SOMAXCONN, so a script
 * that reconnects at once is never refused), one client at a time (a second one is
 * accepted and closed at once). What the client sends is what the host puts on the bus;
 * what it receives is what the host hears (bus.h). Single-threaded, non-blocking, one
 * ppoll() loop.
 *
 * The kind of client is told by its first bytes: IAC (0xFF) then WILL, WONT, DO, DONT or
 * SB is a Telnet client speaking RFC 2217 (rfc2217.h), a UART at the baud it sets; any
 * other first byte is a raw client (no baud rate), as before RFC 2217 was served. Until
 * it is known, what the servos send is not passed on. */
#ifndef CLIENT_H
#define CLIENT_H

#include <netinet/in.h>
#include <signal.h>

/* Listen on sa (port 0: the kernel picks one, written back into sa). Exits with status
 * 2 if that is not possible. Returns the socket. */
int client_listen(struct sockaddr_in *sa, const char *text);

/* Serve clients on the listening socket lfd until *stop is set (by a signal, which is
 * only let through during the poll: poll_mask). */
void client_serve(int lfd, const sigset_t *poll_mask, volatile sig_atomic_t *stop);

#endif
