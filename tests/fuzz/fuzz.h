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
