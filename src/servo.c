/* servo.c - power-up and the main-loop step of one servo. */
#include <string.h>

#include "boot.h"
#include "clock.h"
#include "dispatch.h"
#include "hal.h"
#include "image.h"
#include "loader.h"
#include "motion.h"
#include "servo.h"

/* Register 2: the version in the running image's info block. (A host test that starts
 * the application on blank flash has no image: the build's version then.) Not inlined:
 * measured 16 B smaller as a call, at power-up only. */
__attribute__((noinline)) static uint8_t running_version(struct hal *hal, const struct board *b)
{
    struct image_info info;
    if (image_parse_info(hal_flash_page(hal, HAL_PAGE_APP), &info) &&
        info.model == b->model_number)
        return info.version;
    return SERVO_FW_VERSION;
}

void servo_init(struct servo *s, const struct board *b, struct hal *hal)
{
    memset(s, 0, sizeof *s);
    s->hal = hal;
    s->board = b;
    regs_init(&s->regs, b);
    regs_set(&s->regs, REG_FIRMWARE_VERSION, running_version(hal, b));
    store_load(&s->store, hal, &s->regs, hal_clock_us(hal));
    frame_rx_init(&s->rx, link_baud(b, s->regs.mem[REG_BAUD_RATE]));
    link_latch(s);
    motion_init(s); /* motor off; the goal starts at the present position (rule 1) */
    hal_watchdog_start(s->hal); /* a hang resets the MCU, which comes up with the motor off */
    s->start_us = hal_clock_us(hal);
}

void servo_rx_isr(struct servo *s, uint8_t byte)
{
    frame_rx_byte(&s->rx, byte, hal_clock_us(s->hal));
}

/* The bootloader compiles this file too, for its update mode: there the application's
 * half of the loop is constant-false and the compiler drops it, with every call into
 * motion, dispatch and the store's writer (none of which the bootloader links). The
 * same idiom as Zephyr's IS_ENABLED(). */
#ifdef SERVO_BOOTLOADER
#define APPLICATION(s) false
#else
#define APPLICATION(s) (!loader_running(&(s)->loader))
#endif

/* One pass of the main loop, the store's commit aside. */
static void servo_pass(struct servo *s, uint32_t now)
{
    bool app = APPLICATION(s);
    if (app)
        motion_poll(s, now);
    /* The control tick and the bus handling both run in this loop, so feeding here once
     * per pass proves both alive: a hang in either stops the feeding. */
    hal_watchdog_feed(s->hal);
    uint32_t irq = hal_irq_save(s->hal);
    bool rx_idle = frame_rx_idle(&s->rx, now);
    bool rx_rested = app && frame_rx_quiet(&s->rx, now); /* no erase inside a burst */
    hal_irq_restore(s->hal, irq);
    bool sending = link_state(&s->link) == LINK_SENDING;
    bool link_idle = link_poll(s, now, rx_idle);
    /* Flash work (an erase stalls the CPU) only while nothing moves and the bus rests. */
    bool quiet = link_idle && rx_rested && !s->regs.mem[REG_MOVING];
    if (app) {
        if ((sending && link_idle) || clock_since(now, s->start_us) >= BOOT_CONFIRM_US)
            s->confirm_due = 1; /* an answer's last stop bit is out, or the loop ran a while */
        /* The start is confirmed once this image has answered on the bus or run its main
         * loop for a while (boot.h): a half-word programmed, microseconds. An erase of the
         * record (rare) waits for quiet, and the store's own erase for the next pass: one
         * erase per pass at most. */
        if (!s->confirmed && s->confirm_due) {
            s->confirmed = boot_confirm(s->hal, quiet);
            quiet = false;
        }
        store_poll(&s->store, &s->regs, now, quiet);
    }
    if (link_state(&s->link) == LINK_SENDING)
        return; /* half duplex: nothing arrives for us while we talk */
    if (link_idle && loader_restart_due(&s->loader)) { /* a verified update: its ACK is out */
        if (app) {
            (void)regs_take_ee_changed(&s->regs); /* the flush commits whatever differs */
            store_flush(&s->store, &s->regs, now);
        }
        hal_restart(s->hal); /* the bootloader installs the staged image */
        return;
    }
    (void)update_active(&s->update, now); /* a silent session times out */
    /* A frame is executed even while an earlier answer waits for its return delay or its
     * broadcast PING slot: a stop never waits behind an answer (rule 3). If it gets an
     * answer of its own, that one replaces the waiting one (docs/decisions.md). */
    const struct frame *f = frame_rx_peek(&s->rx);
    if (!f)
        return;
    if (app) {
        dispatch_frame(s, f);
        motion_report(s); /* what the command changed is what the next READ sees */
    } else if (update_is_frame(f->buf, f->len)) /* update mode answers §10 frames only */
        (void)loader_update_frame(s, f);
    frame_rx_release(&s->rx);
    if (link_relatch_due(&s->link))
        link_latch(s); /* no answer: a new ID or baud applies at once */
}

void servo_poll(struct servo *s)
{
    uint32_t now = hal_clock_us(s->hal);
    servo_pass(s, now);
    /* The commit of what this pass changed in EEPROM (a frame, homing's limits), once, at
     * the end of the pass: a frame's answer is only scheduled by dispatch and starts in a
     * later pass (link_poll), so an answered write within the commit budget is in flash
     * before the first byte of its answer leaves. Nothing changed: no store work at all. */
    if (APPLICATION(s)) {
        if (regs_take_ee_lazy(&s->regs))
            store_defer(&s->store);
        if (regs_take_ee_changed(&s->regs))
            store_sync(&s->store, &s->regs, now);
    }
}
