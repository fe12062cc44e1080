/* dispatch.h - the instruction dispatcher (PROTOCOL.md §3.2, §4). Main loop only. */
#ifndef DISPATCH_H
#define DISPATCH_H

#include "frame_rx.h"

struct servo;

/* Execute one received frame and schedule its answer, if it gets one. */
void dispatch_frame(struct servo *s, const struct frame *f);

/* Apply a host write of n bytes at addr the way WRITE does (validation, clamping, side
 * effects). Returns 0 or ERR_INSTRUCTION; nothing is changed on error. */
uint8_t dispatch_write(struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n);

/* RESET (§4.5): factory table, motion stopped, held write and trajectory dropped. */
void dispatch_factory_reset(struct servo *s);

#endif
