/* fuzz.h - what every fuzz target shares: the libFuzzer entry point, the invariant check
 * and, under libFuzzer, a progress line for `make fuzz`.
 *
 * Each target (tests/fuzz/fuzz_*.c) is built two ways from one source: with clang
 * -fsanitize=fuzzer,address,undefined and FUZZ_LIBFUZZER defined (tools/fuzz/fuzz.sh),
 * and with gcc (ASan+UBSan) linked with replay_main.c, a driver that runs every file it is
 * given once: CTest replays each target's corpus (tests/fuzz/corpus/TARGET/) and every
 * past finding (tests/fuzz/findings/TARGET/) that way. */
#ifndef FUZZ_H
#define FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The target's name, for messages (defined by each target). */
extern const char fuzz_target_name[];

/* An invariant: abort on violation, so libFuzzer keeps the input. */
#define FUZZ_CHECK(cond)                                                                    \
    do {                                                                                    \
        if (!(cond)) {                                                                      \
            fprintf(stderr, "%s: invariant failed at %s:%d: %s\n", fuzz_target_name,       \
                    __FILE__, __LINE__, #cond);                                             \
            abort();                                                                        \
        }                                                                                   \
    } while (0)

/* Harness helpers that only loop over bytes (building images, independent CRCs): not
 * traced, they would only slow the fuzzer down. */
#if defined(__clang__) && __clang_major__ >= 13
#define FUZZ_NO_COVERAGE __attribute__((no_sanitize("coverage", "address", "undefined")))
#else
#define FUZZ_NO_COVERAGE
#endif

/* The input read front to back; past its end, bytes read as 0. */
struct fuzz_reader {
    const uint8_t *p;
    size_t left;
};

static inline uint8_t fuzz_get8(struct fuzz_reader *r)
{
    if (!r->left)
        return 0;
    r->left--;
    return *r->p++;
}

/* The wire of fuzz_bus and fuzz_frame, one format so that seeds serve both (fuzz_bus.c
 * has it in full): data bytes, FF FF for a data byte FF, FF FE a power cycle, FF FD k a
 * flash power cut, FF g an idle line. One event at a time; END where the input ends, a
 * pair cut short included. */
enum fuzz_wire { FUZZ_WIRE_END, FUZZ_WIRE_BYTE, FUZZ_WIRE_POWER_CYCLE, FUZZ_WIRE_CUT,
                 FUZZ_WIRE_IDLE };

struct fuzz_wire_event {
    enum fuzz_wire kind;
    uint8_t byte;      /* BYTE */
    uint8_t cut_after; /* CUT: at the cut_after-th next program or erase (1..16) */
    uint8_t cut_kind;  /* CUT: enum flash_cut (clean, done, torn) */
    uint32_t idle_us;  /* IDLE: (g + 1)^2 x 10 us, 10 us ... 0.64 s */
};

static inline struct fuzz_wire_event fuzz_wire_next(struct fuzz_reader *r)
{
    struct fuzz_wire_event e = {FUZZ_WIRE_END, 0, 0, 0, 0};
    if (!r->left)
        return e;
    uint8_t b = fuzz_get8(r);
    if (b != 0xFFu) {
        e.kind = FUZZ_WIRE_BYTE;
        e.byte = b;
        return e;
    }
    if (!r->left)
        return e;
    uint8_t c = fuzz_get8(r);
    if (c == 0xFFu) {
        e.kind = FUZZ_WIRE_BYTE;
        e.byte = 0xFFu;
    } else if (c == 0xFEu) {
        e.kind = FUZZ_WIRE_POWER_CYCLE;
    } else if (c == 0xFDu) {
        if (!r->left)
            return e;
        uint8_t k = fuzz_get8(r);
        e.kind = FUZZ_WIRE_CUT;
        e.cut_after = (uint8_t)((k & 15u) + 1u);
        e.cut_kind = (uint8_t)((k >> 4) % 3u);
    } else {
        e.kind = FUZZ_WIRE_IDLE;
        e.idle_us = (c + 1u) * (c + 1u) * 10u;
    }
    return e;
}

#ifdef FUZZ_LIBFUZZER
#include <time.h>

/* One execution done: every 10 s of wall time, a line for the progress display of
 * tools/fuzz/fuzz.sh (libFuzzer's own status lines come at powers of two only). */
static inline void fuzz_progress(void)
{
    static unsigned long long runs;
    static time_t start, last;
    if ((++runs & 1023u) != 1u)
        return;
    time_t now = time(NULL);
    if (!start)
        start = last = now;
    if (now - last < 10)
        return;
    last = now;
    fprintf(stderr, "fuzz-progress: %llu executions in %lld s, cpu %lld ms\n", runs,
            (long long)(now - start), (long long)(clock() / (CLOCKS_PER_SEC / 1000)));
}
#else
static inline void fuzz_progress(void) {}
#endif

#endif
