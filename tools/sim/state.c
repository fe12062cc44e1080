/* state.c - --state-dir files (state.h). */
#include "state.h"

#include <errno.h>
#include <fcntl.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sim.h"

/* The open files, so the flash wrappers below find the file of a HAL. */
static struct state_file *open_files[SIM_SERVOS_MAX];
static unsigned open_count;

void state_none(struct state_file *f, struct hal *hal)
{
    f->fd = -1;
    f->path = 0;
    f->hal = hal;
    f->synced_ops = hal->flash.ops;
}

/* A pwrite() of one 1 KiB page inside one 4 KiB file page reaches the page cache whole
 * or not at all, so a SIGKILL never tears a page; the host kernel keeps the data even if
 * this process dies, so there is no fsync (a host crash is not the power cut modelled). */
void state_write(struct state_file *f)
{
    if (f->fd < 0)
        return;
    for (unsigned p = 0; p < STATE_PAGES; p++) {
        if (memcmp(f->hal->flash.mem[p], f->saved[p], HAL_FLASH_PAGE_BYTES) == 0)
            continue;
        ssize_t n = pwrite(f->fd, f->hal->flash.mem[p], HAL_FLASH_PAGE_BYTES,
                           (off_t)p * HAL_FLASH_PAGE_BYTES);
        if (n != (ssize_t)HAL_FLASH_PAGE_BYTES)
            die(1, "cannot write %s: %s", f->path, n < 0 ? strerror(errno) : "short write");
        memcpy(f->saved[p], f->hal->flash.mem[p], HAL_FLASH_PAGE_BYTES);
    }
    f->synced_ops = f->hal->flash.ops;
}

void state_sync(struct state_file *f)
{
    if (f->hal->flash.ops != f->synced_ops)
        state_write(f);
}

/* The linker routes the core's flash operations here (-Wl,--wrap, tools/CMakeLists.txt)
 * so the file follows the flash operation by operation, not just once per main-loop
 * step: a SIGKILL lands between two operations, as a power cut between them would. */
bool __real_hal_flash_erase(struct hal *h, uint8_t p);
bool __real_hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value);
bool __wrap_hal_flash_erase(struct hal *h, uint8_t p);
bool __wrap_hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value);

static void sync_hal(const struct hal *h)
{
    for (unsigned i = 0; i < open_count; i++)
        if (open_files[i]->hal == h)
            state_sync(open_files[i]);
}

bool __wrap_hal_flash_erase(struct hal *h, uint8_t p)
{
    bool ok = __real_hal_flash_erase(h, p);
    sync_hal(h);
    return ok;
}

bool __wrap_hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value)
{
    bool ok = __real_hal_flash_program(h, p, off, value);
    sync_hal(h);
    return ok;
}

/* A file of an older layout (fewer pages): its pages are kept, the file is extended
 * with erased pages to the current layout. */
static void extend(struct state_file *f, size_t bytes)
{
    unsigned page = (unsigned)(bytes / HAL_FLASH_PAGE_BYTES);
    if (pwrite(f->fd, f->hal->flash.mem[page], STATE_BYTES - bytes, (off_t)bytes) !=
        (ssize_t)(STATE_BYTES - bytes))
        die(2, "cannot extend state file %s: %s", f->path, strerror(errno));
    fprintf(stderr, "servo-sim: %s: a file of %zu KiB from an older servo-sim, extended "
            "to %u KiB (its new pages erased)\n", f->path, bytes / 1024u, STATE_BYTES / 1024u);
}

void state_open(struct state_file *f, struct hal *hal, const char *dir, uint8_t id,
                const char *variant, const uint8_t *uid)
{
    state_none(f, hal);
    size_t len = strlen(dir) + 64u;
    f->path = malloc(len);
    if (!f->path)
        die(1, "out of memory");
    int at = snprintf(f->path, len, "%s/servo-%u-%s", dir, id, variant);
    for (unsigned i = 0; uid && i < HAL_UID_BYTES; i++)
        at += snprintf(f->path + at, len - (size_t)at, "%s%02x", i ? "" : "-", uid[i]);
    snprintf(f->path + at, len - (size_t)at, ".flash");
    f->fd = open(f->path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (f->fd < 0)
        die(2, "cannot open state file %s: %s", f->path, strerror(errno));
    if (flock(f->fd, LOCK_EX | LOCK_NB) != 0)
        die(2, "state file %s is in use by another servo-sim", f->path);
    struct stat st;
    if (fstat(f->fd, &st) != 0)
        die(2, "cannot stat state file %s: %s", f->path, strerror(errno));
    size_t bytes = (size_t)st.st_size;
    if (bytes > STATE_BYTES || bytes % HAL_FLASH_PAGE_BYTES ||
        (bytes && bytes < HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES))
        die(2, "state file %s has %lld bytes, not %u: not a servo-sim flash image", f->path,
            (long long)st.st_size, STATE_BYTES);
    /* hal_host_init() left the flash erased: a new file, or the pages it lacks. */
    if (bytes && pread(f->fd, hal->flash.mem, bytes, 0) != (ssize_t)bytes)
        die(2, "cannot read state file %s: %s", f->path, strerror(errno));
    if (bytes < STATE_BYTES && bytes)
        extend(f, bytes);
    else if (!bytes && pwrite(f->fd, hal->flash.mem, STATE_BYTES, 0) != (ssize_t)STATE_BYTES)
        die(2, "cannot write state file %s: %s", f->path, strerror(errno));
    memcpy(f->saved, hal->flash.mem, sizeof f->saved);
    open_files[open_count++] = f;
}

void state_close(struct state_file *f)
{
    for (unsigned i = 0; i < open_count; i++)
        if (open_files[i] == f)
            open_files[i] = open_files[--open_count];
    if (f->fd >= 0)
        close(f->fd);
    free(f->path);
    f->fd = -1;
    f->path = 0;
}
