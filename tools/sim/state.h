/* state.h - --state-dir: each servo's simulated flash in DIR/servo-<ID>-<variant>.flash
 * (ID as given on the command line, so a later change of ID keeps the file), every page
 * the host HAL's flash has (flash_sim.h), in page order. It is loaded before the servo
 * powers up and written back page by page (pwrite of each changed 1 KiB page in place)
 * right after every flash operation, so a SIGKILL at any moment is a power cut between
 * two flash operations. The file is locked: two simulators cannot share a servo.
 *
 * Layouts only ever grew by pages at the end (the store's 4 pages; then both image
 * slots). A shorter file of whole pages is from an older servo-sim: it is extended in
 * place once, when opened, with erased pages, and is then an ordinary file. */
#ifndef STATE_H
#define STATE_H

#include <stdint.h>

#include "hal_host.h"

#define STATE_PAGES ((unsigned)(sizeof ((struct flash_sim *)0)->mem / HAL_FLASH_PAGE_BYTES))
#define STATE_BYTES (STATE_PAGES * HAL_FLASH_PAGE_BYTES)

struct state_file {
    int fd;              /* -1: no file (no --state-dir) */
    char *path;
    struct hal *hal;     /* whose flash the file follows */
    uint32_t synced_ops; /* hal->flash.ops when the file last matched the flash */
    uint8_t saved[STATE_PAGES][HAL_FLASH_PAGE_BYTES]; /* what the file holds */
};

/* No file: the flash lives and dies with the process. */
void state_none(struct state_file *f, struct hal *hal);

/* Open (or create) DIR/servo-<id>-<variant>.flash, or with a uid (12 bytes)
 * DIR/servo-<id>-<variant>-<uid in hex>.flash, and load it into hal's flash (before
 * the servo powers up: the store reads it there). A new file starts erased. Exits with
 * status 2 on a file that is not a servo-sim flash image, or is in use. */
void state_open(struct state_file *f, struct hal *hal, const char *dir, uint8_t id,
                const char *variant, const uint8_t *uid);

/* Write every page that differs from the file (a programmer's direct write, e.g. the
 * factory image, is not a counted flash operation: call this after it). */
void state_write(struct state_file *f);

/* The same, only if the core ran a flash operation since (the usual case: none). */
void state_sync(struct state_file *f);

void state_close(struct state_file *f);

#endif
