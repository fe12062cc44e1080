/* boot.h - the power-on decision, shared by the STM32 bootloader and the host model of
 * a servo (servo_power_on), and the boot record that lets it refuse an application that
 * never confirms that it runs. Main loop / bootloader only. */
#ifndef BOOT_H
#define BOOT_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

/* Install a verified update if one is waiting, then say whether the application slot
 * holds a valid image for this model (start it) or not (stay in the loader).
 *
 * A staged image is installed when the install mark is set (image.h), the staging slot
 * holds a valid image and it differs from the application slot: page by page, erase
 * then program then compare. A power cut anywhere in the copy leaves the staging copy
 * valid and the slots different, so the next boot simply copies again. Once the slots
 * match, the boot record is erased (the new image starts with no failed start against
 * it), then the staging copy is consumed (its first page erased); a cut before that
 * consumption redoes both at the next boot. Nothing is written when there is nothing to
 * install. */
bool boot_install(struct hal *hal, uint16_t model);

/* Boot record (docs/update.md, "Boot confirmation"): flash page HAL_PAGE_BOOTREC, a log of
 * half-word marks, each programmed into the next erased half-word from offset 0 up (no
 * erase per start):
 *   BOOT_MARK_START    written by the bootloader just before it starts the application
 *   BOOT_MARK_CONFIRM  written by the application once it runs: its first answer has
 *                      left the wire, or its main loop has run BOOT_CONFIRM_US
 * The log is read up to its first erased half-word; the starts after the last confirm
 * are the unconfirmed ones. With BOOT_STARTS_MAX of them the bootloader does not start
 * the application again: it stays in update mode until a new image is installed.
 *
 * Torn marks: a START only ever clears bits of the low byte, a CONFIRM of the high byte,
 * so a half-word cut while being programmed reads as erased or as the mark that was
 * being written, never as the other one. A torn erase only sets bits: a START reads as a
 * START or erased, a CONFIRM as a CONFIRM or erased, so what is read up to the first
 * erased half-word is an exact prefix of the log before the erase. */
#define BOOT_MARK_START 0xFF00u   /* high byte erased */
#define BOOT_MARK_CONFIRM 0x00FFu /* high byte programmed */
#define BOOT_STARTS_MAX 3u
#define BOOT_CONFIRM_US 2000000u
#define BOOT_TIDY_BYTES (HAL_FLASH_PAGE_BYTES / 2u) /* the application erases from here */

/* Starts not confirmed since the last confirm (or erase), and in *end the byte offset of
 * the record's first erased half-word (HAL_FLASH_PAGE_BYTES: the page is full, or the
 * port has no boot record). */
uint16_t boot_unconfirmed(struct hal *hal, uint16_t *end);

/* The bootloader's whole decision: boot_install(), then, if the application is valid
 * and has fewer than BOOT_STARTS_MAX unconfirmed starts, record one more start and
 * return true: start it, with the watchdog running. False: stay in update mode. The
 * port must map HAL_PAGE_BOOTREC. */
bool boot_start(struct hal *hal, uint16_t model);

/* The application: confirm the start the bootloader recorded, if there is one. A record
 * that is half full (BOOT_TIDY_BYTES), or holds marks past its first erased half-word
 * (what a torn erase leaves), is then erased, once quiet says the CPU may stall for an
 * erase. True once nothing is left to do; until then, call again (each call reads the
 * record afresh and writes a confirm only while a start is unconfirmed). */
bool boot_confirm(struct hal *hal, bool quiet);

#endif
