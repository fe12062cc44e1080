/* port_boot_unused.c - the application's half of src/servo.c, which the bootloader's
 * build compiles out (APPLICATION() is constant false under SERVO_BOOTLOADER and the
 * MCU's -Os link drops it); the host's unoptimised build still refers to these. Never
 * called: each stops the test if it is. */
#include <stdio.h>
#include <stdlib.h>

#include "boot.h"
#include "dispatch.h"
#include "motion.h"
#include "servo.h"

static void never(const char *what)
{
    fprintf(stderr, "port.boot: the bootloader called the application's %s\n", what);
    abort();
}

void motion_init(struct servo *s)
{
    (void)s;
    never("motion_init");
}

void motion_poll(struct servo *s, uint32_t now_us)
{
    (void)s;
    (void)now_us;
    never("motion_poll");
}

void motion_report(struct servo *s)
{
    (void)s;
    never("motion_report");
}

void dispatch_frame(struct servo *s, const struct frame *f)
{
    (void)s;
    (void)f;
    never("dispatch_frame");
}

bool boot_confirm(struct hal *hal, bool quiet)
{
    (void)hal;
    (void)quiet;
    never("boot_confirm");
    return false;
}
