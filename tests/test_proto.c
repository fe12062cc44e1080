/* test_proto.c - checksum and status packet encoding against PROTOCOL.md §2-§4 and the
 * byte-exact examples of the spec (VECTORS.md). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "proto.h"

/* §2: the source's worked example, broadcast WRITE ID := 1, checksums to 0x09. */
static void sum_of_source_example_is_0x09(void **state)
{
    (void)state;
    const uint8_t pkt[] = {0xD5, 0x5D, 0xFE, 0x04, 0x03, 0x03, 0x01, 0x09};
    /* CHK covers ID .. last parameter, not the header. */
    assert_int_equal(proto_sum(&pkt[2], 5), 0x09);
}

/* §2: the plain sum, not inverted, kept to 8 bits. */
static void sum_is_plain_and_wraps(void **state)
{
    (void)state;
    const uint8_t ping[] = {0x01, 0x02, 0x01};
    assert_int_equal(proto_sum(ping, 3), 0x04); /* PING servo 1: D5 5D 01 02 01 04 */
    const uint8_t wrap[] = {0xFF, 0xFF, 0x03};
    assert_int_equal(proto_sum(wrap, 3), 0x01); /* 0x201 & 0xFF */
    assert_int_equal(proto_sum(wrap, 0), 0x00);
    uint8_t many[300];
    memset(many, 0x01, sizeof many);
    assert_int_equal(proto_sum(many, 300), 300 & 0xFF);
}

static void expect_status(uint8_t id, uint8_t err, const uint8_t *data, uint8_t n,
                          const uint8_t *want, uint16_t want_len)
{
    uint8_t out[PROTO_STATUS_MAX + 8];
    memset(out, 0xA5, sizeof out);
    uint16_t len = proto_build_packet(out, id, err, data, n);
    assert_int_equal(len, want_len);
    assert_memory_equal(out, want, want_len);
    for (size_t i = want_len; i < sizeof out; i++)
        assert_int_equal(out[i], 0xA5); /* nothing written past the packet */
}

/* §4.1: a healthy servo 1 answers PING with exactly D5 5D 01 03 01 00 05. */
static void ping_answer_is_byte_exact(void **state)
{
    (void)state;
    const uint8_t err = 0x00;
    const uint8_t want[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x00, 0x05};
    expect_status(0x01, 0x01, &err, 1, want, sizeof want);
    const uint8_t hot = 0x01; /* over-temperature */
    const uint8_t want_hot[] = {0xD5, 0x5D, 0x01, 0x03, 0x01, 0x01, 0x06};
    expect_status(0x01, 0x01, &hot, 1, want_hot, sizeof want_hot);
}

/* §3: answers without parameters (instruction error, checksum error, plain OK). */
static void answers_without_parameters(void **state)
{
    (void)state;
    const uint8_t ins_err[] = {0xD5, 0x5D, 0x01, 0x02, 0x20, 0x23};
    expect_status(0x01, ERR_INSTRUCTION, 0, 0, ins_err, sizeof ins_err);
    const uint8_t sum_err[] = {0xD5, 0x5D, 0x01, 0x02, 0x10, 0x13};
    expect_status(0x01, ERR_CHECKSUM, 0, 0, sum_err, sizeof sum_err);
    const uint8_t ok[] = {0xD5, 0x5D, 0x01, 0x02, 0x00, 0x03};
    expect_status(0x01, 0x00, 0, 0, ok, sizeof ok);
}

/* §4.2: READ answers carry ERR then the bytes read (VECTORS.md). */
static void read_answers_are_byte_exact(void **state)
{
    (void)state;
    const uint8_t id = 0x01;
    const uint8_t want_id[] = {0xD5, 0x5D, 0x01, 0x03, 0x00, 0x01, 0x05};
    expect_status(0x01, 0x00, &id, 1, want_id, sizeof want_id);
    const uint8_t two[] = {0x02, 0x01};
    const uint8_t want_two[] = {0xD5, 0x5D, 0x01, 0x04, 0x00, 0x02, 0x01, 0x08};
    expect_status(0x01, 0x00, two, 2, want_two, sizeof want_two);
    /* A high ID whose sum wraps. */
    const uint8_t ff[] = {0xFF, 0xFF};
    const uint8_t want_ff[] = {0xD5, 0x5D, 0xFD, 0x04, 0x40, 0xFF, 0xFF, 0x3F};
    expect_status(0xFD, ERR_STALL, ff, 2, want_ff, sizeof want_ff);
}

/* The longest answer, a READ of the whole table, fits PROTO_STATUS_MAX exactly: it is
 * derived from the table's size, so a register added to the table grows it. */
static void whole_table_read_fits(void **state)
{
    (void)state;
    uint8_t data[REGS_SIZE];
    uint32_t sum = 0x01u + (REGS_SIZE + 2u) + 0x00u;
    for (uint8_t i = 0; i < REGS_SIZE; i++) {
        data[i] = (uint8_t)(i * 7u + 3u);
        sum += data[i];
    }
    uint8_t want[PROTO_STATUS_MAX] = {0xD5, 0x5D, 0x01, REGS_SIZE + 2u, 0x00};
    memcpy(&want[5], data, REGS_SIZE);
    want[PROTO_STATUS_MAX - 1u] = (uint8_t)sum;
    assert_int_equal(PROTO_STATUS_MAX, 6u + REGS_SIZE);
    expect_status(0x01, 0x00, data, REGS_SIZE, want, sizeof want);
}

/* The checksum of a built packet is what a receiver recomputes (§3). */
static void built_checksum_verifies(void **state)
{
    (void)state;
    uint8_t out[PROTO_STATUS_MAX];
    for (uint8_t n = 0; n <= REGS_SIZE; n++) {
        uint8_t data[REGS_SIZE];
        for (uint8_t i = 0; i < n; i++)
            data[i] = (uint8_t)(0xF0u + i);
        uint16_t len = proto_build_packet(out, 0xAB, 0x5A, data, n);
        assert_int_equal(len, n + 6u);
        assert_int_equal(out[3], n + 2u);
        assert_int_equal(out[len - 1u], proto_sum(&out[2], (uint16_t)(len - 3u)));
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(sum_of_source_example_is_0x09),
        cmocka_unit_test(sum_is_plain_and_wraps),
        cmocka_unit_test(ping_answer_is_byte_exact),
        cmocka_unit_test(answers_without_parameters),
        cmocka_unit_test(read_answers_are_byte_exact),
        cmocka_unit_test(whole_table_read_fits),
        cmocka_unit_test(built_checksum_verifies),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
