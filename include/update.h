/* update.h - the firmware update session of PROTOCOL.md §10 (YMODEM blocks in `D5 5D`
 * frames, CUSTOM sub-commands 0xFC/0xFE), run by the application and by the loader.
 *
 * The image is written to the staging slot only, block n to staging page n-1 (erase,
 * program, read back). The running image is untouched until the whole new image has
 * arrived and passes image_valid(); then the install mark is set (image.h), the
 * servo restarts and the bootloader installs it (boot.h). See docs/update.md for the state machine and the decisions.
 * Main loop only. */
#ifndef UPDATE_H
#define UPDATE_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"
#include "proto.h"

/* The frame shapes are proto.h's (PROTO_UPDATE_*): the receiver knows the data block. */
#define UPDATE_ACK 0x06u
#define UPDATE_NAK 0x15u
#define UPDATE_CAN 0x18u
#define UPDATE_READY 0x43u /* 'C' */
/* A session with no update frame for this long is abandoned (the motor stays off). */
#define UPDATE_TIMEOUT_US 10000000u

enum update_state {
    UPDATE_IDLE,    /* no session */
    UPDATE_ENTERED, /* 'C' sent, waiting for the header block */
    UPDATE_DATA,    /* header taken, data blocks arriving */
    UPDATE_EOF,     /* end of file taken, waiting for the end-of-batch header */
};

/* What the caller does after the answer. */
enum update_outcome {
    UPDATE_GO_ON,     /* nothing */
    UPDATE_STARTED,   /* a session began: stop the motor, torque off */
    UPDATE_RESTART,   /* the new image is staged and verified: restart once answered */
    UPDATE_ABANDONED, /* CAN answered: the session is over, the old image stays */
};

struct update {
    uint8_t state;   /* enum update_state */
    uint8_t next;    /* number of the data block expected next (1, 2, ...) */
    uint8_t blocks;  /* data blocks the header announced */
    uint32_t length; /* image length from the header block */
    uint32_t last_us; /* arrival of the last update frame */
};

/* A session is open: the servo only reports (PING, READ) until it ends. */
static inline bool update_in_session(const struct update *u)
{
    return u->state != UPDATE_IDLE;
}

/* Is this frame (buf = ID, LEN, INS, params..., CHK; len bytes) a §10 frame, i.e.
 * instruction 0xFF with sub-command 0xFC or 0xFE? */
bool update_is_frame(const uint8_t *buf, uint16_t len);

/* One §10 frame addressed to this servo (chk_ok: its checksum matched). Writes the
 * answer's data bytes (after ERR = 0) to ans[0..*n) and says what to do next. */
uint8_t update_frame(struct update *u, struct hal *hal, uint16_t model, const uint8_t *buf,
                     uint16_t len, bool chk_ok, uint32_t now_us, uint8_t ans[2], uint8_t *n);

/* Main loop: true while a session is open; a silent session times out here. */
bool update_active(struct update *u, uint32_t now_us);

#endif
