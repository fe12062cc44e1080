/* test_wire.c - the bus line at the bit level (hal/host/wire.c): what a UART receives
 * from talkers at its own baud, at another baud, and from two talkers at once. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "wire.h"

/* Every baud of PROTOCOL.md §5.2. */
static const uint32_t bauds[] = {2400, 9600, 38400, 115200, 256000, 460800,
                                 896000, 921600, 1280000, 1792000};
#define NBAUDS (sizeof bauds / sizeof bauds[0])

static const uint8_t ping_answer[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x00, 0x05};
static const uint8_t read_request[] = {0xD5, 0x5D, 0x01, 0x04, 0x02, 0x24, 0x02, 0x2D};

/* Talker puts n bytes back to back from t0, as a UART sends them. */
static void send(struct wire *w, unsigned talker, int64_t t0, uint32_t baud, const uint8_t *p,
                 size_t n)
{
    for (size_t i = 0; i < n; i++)
        wire_put(w, talker, wire_bit_ns(t0, baud, 10u * (unsigned)i), baud, p[i]);
}

struct heard {
    size_t n, framing_errors;
    uint8_t byte[256];
    int64_t end_ns[256];
};

/* Everything a receiver at baud (0: every baud) hears from hunt on. */
static void listen_all(const struct wire *w, uint32_t baud, int64_t hunt, struct heard *h)
{
    struct wire_rx rx = {baud, hunt};
    struct wire_rx_byte b;
    memset(h, 0, sizeof *h);
    while (wire_rx_next(w, &rx, &b)) {
        assert_true(b.stop_ns > rx.hunt_ns);
        wire_rx_take(&rx, &b);
        if (!b.framing_ok) {
            h->framing_errors++;
            continue;
        }
        assert_true(h->n < sizeof h->byte);
        h->end_ns[h->n] = b.end_ns;
        h->byte[h->n++] = b.byte;
    }
}

/* Does the packet occur in what was heard? */
static bool contains(const struct heard *h, const uint8_t *p, size_t n)
{
    for (size_t i = 0; i + n <= h->n; i++)
        if (memcmp(&h->byte[i], p, n) == 0)
            return true;
    return false;
}

static void same_baud_hears_every_byte_at_its_end(void **state)
{
    (void)state;
    for (size_t k = 0; k < NBAUDS; k++) {
        struct wire w;
        wire_init(&w, 1);
        int64_t t0 = 1000000 + (int64_t)k * 333; /* any phase */
        send(&w, 0, t0, bauds[k], ping_answer, sizeof ping_answer);
        struct heard h;
        listen_all(&w, bauds[k], 0, &h);
        assert_int_equal(h.n, sizeof ping_answer);
        assert_int_equal(h.framing_errors, 0);
        assert_memory_equal(h.byte, ping_answer, sizeof ping_answer);
        for (size_t i = 0; i < h.n; i++) /* the end of its stop bit, to the nanosecond */
            assert_true(h.end_ns[i] - wire_bit_ns(t0, bauds[k], 10u * (unsigned)(i + 1u)) <= 1 &&
                        h.end_ns[i] - wire_bit_ns(t0, bauds[k], 10u * (unsigned)(i + 1u)) >= -1);
        wire_free(&w);
    }
}

/* Bauds within 5 % of each other: a UART samples each bit mid-bit, so 10 bits stay
 * inside their cells up to about 4.5 % of mismatch. */
static bool close_bauds(uint32_t a, uint32_t b)
{
    uint32_t hi = a > b ? a : b, lo = a > b ? b : a;
    return (uint64_t)(hi - lo) * 20u < lo;
}

/* The premise of servo-sim's baud model: at any other baud of the table the packet does
 * not arrive (framing errors, garbage, or nothing), except the one pair close enough
 * for a UART to read across. */
static void another_baud_never_hears_the_packet(void **state)
{
    (void)state;
    for (size_t tx = 0; tx < NBAUDS; tx++) {
        for (size_t rx = 0; rx < NBAUDS; rx++) {
            if (rx == tx || close_bauds(bauds[rx], bauds[tx]))
                continue;
            for (int64_t phase = 0; phase < 3000; phase += 1000) {
                struct wire w;
                wire_init(&w, 1);
                send(&w, 0, 1000000 + phase, bauds[tx], read_request, sizeof read_request);
                struct heard h;
                listen_all(&w, bauds[rx], 0, &h);
                assert_false(contains(&h, read_request, sizeof read_request));
                assert_false(contains(&h, read_request, 2)); /* not even the header */
                wire_free(&w);
            }
        }
    }
}

/* 896000 and 921600 baud are 2.8 % apart: as between real UARTs, each reads the other.
 * (A host at one of them finds servos at the other.) */
static void close_bauds_read_each_other(void **state)
{
    (void)state;
    assert_true(close_bauds(896000, 921600));
    int pairs = 0;
    for (size_t tx = 0; tx < NBAUDS; tx++)
        for (size_t rx = 0; rx < NBAUDS; rx++) {
            if (rx == tx || !close_bauds(bauds[rx], bauds[tx]))
                continue;
            pairs++;
            struct wire w;
            wire_init(&w, 1);
            send(&w, 0, 1000000, bauds[tx], read_request, sizeof read_request);
            struct heard h;
            listen_all(&w, bauds[rx], 0, &h);
            assert_int_equal(h.n, sizeof read_request);
            assert_memory_equal(h.byte, read_request, sizeof read_request);
            wire_free(&w);
        }
    assert_int_equal(pairs, 2);
}

/* A slow sender heard by a fast receiver: the start bit alone fills a whole frame of
 * zeros, whose stop bit is 0: framing errors, not bytes. */
static void fast_receiver_sees_framing_errors(void **state)
{
    (void)state;
    struct wire w;
    wire_init(&w, 1);
    send(&w, 0, 0, 9600, read_request, sizeof read_request);
    struct heard h;
    listen_all(&w, 115200, -1, &h);
    assert_true(h.framing_errors >= sizeof read_request);
    wire_free(&w);
}

/* A receiver of every baud (servo-sim's raw host) hears talkers at different bauds. */
static void every_baud_receiver_follows_each_talker(void **state)
{
    (void)state;
    struct wire w;
    wire_init(&w, 3);
    send(&w, 0, 1000, 9600, ping_answer, sizeof ping_answer);
    send(&w, 1, 20000000, 115200, read_request, sizeof read_request);
    send(&w, 2, 30000000, 1792000, ping_answer, sizeof ping_answer);
    struct heard h;
    listen_all(&w, 0, 0, &h);
    assert_int_equal(h.n, 2 * sizeof ping_answer + sizeof read_request);
    assert_memory_equal(h.byte, ping_answer, sizeof ping_answer);
    assert_memory_equal(&h.byte[sizeof ping_answer], read_request, sizeof read_request);
    assert_memory_equal(&h.byte[sizeof ping_answer + sizeof read_request], ping_answer,
                        sizeof ping_answer);
    wire_free(&w);
}

/* The line is the AND of the talkers. */
static void line_is_the_and_of_the_talkers(void **state)
{
    (void)state;
    struct wire w;
    wire_init(&w, 2);
    assert_int_equal(wire_level(&w, 5), 1); /* idle high */
    uint8_t a = 0xF0, b = 0x3C;
    wire_put(&w, 0, 0, 1000000, a); /* 1 us bits */
    wire_put(&w, 1, 0, 1000000, b);
    assert_int_equal(wire_level(&w, 500), 0); /* both start bits */
    for (unsigned k = 0; k < 8; k++)
        assert_int_equal(wire_level(&w, 1500 + 1000 * (int64_t)k), ((unsigned)(a & b) >> k) & 1u);
    assert_int_equal(wire_level(&w, 9500), 1); /* both stop bits */
    struct heard h;
    listen_all(&w, 1000000, 0, &h);
    assert_int_equal(h.n, 1);
    assert_int_equal(h.byte[0], a & b);
    wire_free(&w);
}

/* Two talkers with the same packet: within half a bit of each other the line shows it
 * (the later edges fall inside the earlier bits), at a whole bit or more it is garbled.
 * That is why two servos with one ID are invisible to a PING at 9600 baud and visible
 * at 1 Mbaud (bus.h). */
static void same_packet_superimposes_within_half_a_bit(void **state)
{
    (void)state;
    for (size_t k = 0; k < NBAUDS; k++) {
        uint32_t baud = bauds[k];
        int64_t bit = WIRE_NS_PER_S / baud;
        struct wire w;
        struct heard h;
        wire_init(&w, 2);
        send(&w, 0, 1000000, baud, ping_answer, sizeof ping_answer);
        send(&w, 1, 1000000 + bit / 3, baud, ping_answer, sizeof ping_answer);
        listen_all(&w, baud, 0, &h);
        assert_int_equal(h.n, sizeof ping_answer);
        assert_memory_equal(h.byte, ping_answer, sizeof ping_answer);
        wire_free(&w);

        wire_init(&w, 2);
        send(&w, 0, 1000000, baud, ping_answer, sizeof ping_answer);
        send(&w, 1, 1000000 + bit + bit / 2, baud, ping_answer, sizeof ping_answer);
        listen_all(&w, baud, 0, &h);
        assert_false(contains(&h, ping_answer, sizeof ping_answer));
        wire_free(&w);
    }
}

/* Two different answers at once garble each other at any offset. */
static void two_answers_at_once_garble(void **state)
{
    (void)state;
    uint8_t other[sizeof ping_answer];
    memcpy(other, ping_answer, sizeof other);
    other[2] = 0x02; /* ID 2 */
    other[6] = 0x04;
    for (int64_t offset = 0; offset < 1041667; offset += 50000) {
        struct wire w;
        struct heard h;
        wire_init(&w, 2);
        send(&w, 0, 1000000, 9600, ping_answer, sizeof ping_answer);
        send(&w, 1, 1000000 + offset, 9600, other, sizeof other);
        listen_all(&w, 9600, 0, &h);
        assert_false(contains(&h, ping_answer, sizeof ping_answer));
        assert_false(contains(&h, other, sizeof other));
        wire_free(&w);
    }
}

/* A line held low for nine bits at 2400 baud (0x00) is one framing error at 9600, then
 * nothing until the line has risen and falls again. */
static void a_long_low_is_one_framing_error(void **state)
{
    (void)state;
    struct wire w;
    wire_init(&w, 1);
    wire_put(&w, 0, 1000, 2400, 0x00);
    struct heard h;
    listen_all(&w, 9600, 0, &h);
    assert_int_equal(h.n, 0);
    assert_int_equal(h.framing_errors, 1);
    wire_free(&w);
}

static void busy_drop_and_prune(void **state)
{
    (void)state;
    struct wire w;
    wire_init(&w, 1);
    send(&w, 0, 0, 1000000, ping_answer, sizeof ping_answer); /* 10 us per byte */
    assert_true(wire_talker_busy(&w, 0, 0));
    assert_true(wire_talker_busy(&w, 0, 69999));
    assert_false(wire_talker_busy(&w, 0, 70000));
    assert_int_equal(wire_talker_end(&w, 0), 70000);
    assert_int_equal(wire_talker_free_at(&w, 0, 15000), 20000);
    assert_int_equal(wire_talker_free_at(&w, 0, 90000), 90000);
    wire_drop_after(&w, 0, 25000); /* bytes 3.. had not started */
    assert_int_equal(wire_talker_end(&w, 0), 30000);
    wire_prune(&w, 25000); /* bytes 0 and 1 ended before */
    struct heard h;
    listen_all(&w, 1000000, 0, &h);
    assert_int_equal(h.n, 1);
    assert_int_equal(h.byte[0], ping_answer[2]);
    wire_free(&w);
}

/* A ring that grows: a long burst from one talker (a firmware update) decodes whole. */
static void a_long_burst_decodes_whole(void **state)
{
    (void)state;
    static uint8_t data[5000];
    for (size_t i = 0; i < sizeof data; i++)
        data[i] = (uint8_t)(i * 7u + 3u);
    struct wire w;
    wire_init(&w, 2);
    send(&w, 1, 0, 921600, data, sizeof data);
    struct wire_rx rx = {921600, 0};
    struct wire_rx_byte b;
    for (size_t i = 0; i < sizeof data; i++) {
        assert_true(wire_rx_next(&w, &rx, &b));
        assert_true(b.framing_ok);
        assert_int_equal(b.byte, data[i]);
        wire_rx_take(&rx, &b);
        if (i % 100 == 0)
            wire_prune(&w, rx.hunt_ns - 1);
    }
    assert_false(wire_rx_next(&w, &rx, &b));
    wire_free(&w);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(same_baud_hears_every_byte_at_its_end),
        cmocka_unit_test(another_baud_never_hears_the_packet),
        cmocka_unit_test(close_bauds_read_each_other),
        cmocka_unit_test(fast_receiver_sees_framing_errors),
        cmocka_unit_test(every_baud_receiver_follows_each_talker),
        cmocka_unit_test(line_is_the_and_of_the_talkers),
        cmocka_unit_test(same_packet_superimposes_within_half_a_bit),
        cmocka_unit_test(two_answers_at_once_garble),
        cmocka_unit_test(a_long_low_is_one_framing_error),
        cmocka_unit_test(busy_drop_and_prune),
        cmocka_unit_test(a_long_burst_decodes_whole),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
