/* bench.c - workloads for `make bench`. Run under callgrind by tools/bench.sh, which
 * counts the instructions spent inside the function under test; `latency` prints reply
 * latencies in virtual time directly.
 *
 *   bench rx N        N bytes of typical traffic through frame_rx_byte (the UART ISR path)
 *   bench read N      N READ frames through dispatch_frame
 *   bench write N     N WRITE frames through dispatch_frame
 *   bench sync N      N SYNC WRITE frames (8 servos x 2 bytes) through dispatch_frame
 *   bench latency     reply latency on the virtual bus with return delay 0
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dispatch.h"
#include "frame_rx.h"
#include "hal_host.h"
#include "proto.h"
#include "servo.h"
#include "vbus.h"

static const uint8_t read_params[] = {REG_PRESENT_SPEED, 6};
static const uint8_t write_params[] = {REG_GOAL_POSITION, 0x2C, 0x01, 0x64, 0x00};
static const uint8_t sync_params[] = {REG_MOVING_SPEED, 2, 1, 0x64, 0, 2, 0x64, 0, 3, 0x64, 0,
                                      4, 0x64, 0, 5, 0x64, 0, 6, 0x64, 0, 7, 0x64, 0, 8, 0x64, 0};

static int bench_rx(long n)
{
    static struct frame_rx rx;
    frame_rx_init(&rx, 1000000);
    uint8_t stream[256];
    uint16_t len = 0;
    len = (uint16_t)(len + proto_build_packet(&stream[len], 1, INS_READ, read_params, sizeof read_params));
    len = (uint16_t)(len + proto_build_packet(&stream[len], 1, INS_WRITE, write_params, sizeof write_params));
    len = (uint16_t)(len + proto_build_packet(&stream[len], PROTO_ID_BROADCAST, INS_SYNC_WRITE, sync_params,
                                  sizeof sync_params));
    len = (uint16_t)(len + proto_build_packet(&stream[len], 1, INS_PING, 0, 0));
    uint32_t t = 0, frames = 0;
    for (long i = 0; i < n; i++) {
        frame_rx_byte(&rx, stream[i % len], t += 10);
        while (frame_rx_peek(&rx)) {
            frame_rx_release(&rx);
            frames++;
        }
    }
    printf("bytes %ld frames %u overruns %u\n", n, frames, rx.overruns);
    return 0;
}

static int bench_dispatch(const char *what, long n)
{
    static struct hal hal;
    static struct servo s;
    hal_host_init(&hal);
    servo_init(&s, &board_foot, &hal);
    uint8_t raw[300];
    uint16_t len;
    if (strcmp(what, "read") == 0)
        len = proto_build_packet(raw, 1, INS_READ, read_params, sizeof read_params);
    else if (strcmp(what, "write") == 0)
        len = proto_build_packet(raw, 1, INS_WRITE, write_params, sizeof write_params);
    else
        len = proto_build_packet(raw, PROTO_ID_BROADCAST, INS_SYNC_WRITE, sync_params, sizeof sync_params);
    static struct frame f;
    static uint8_t buf[FRAME_BYTES];
    f.buf = buf;
    memcpy(f.buf, &raw[2], (size_t)(len - 2u));
    f.len = (uint16_t)(len - 2u);
    f.status = FRAME_OK;
    for (long i = 0; i < n; i++) {
        dispatch_frame(&s, &f);
        s.link.state = LINK_IDLE; /* the answer is dropped: only the dispatch is measured */
    }
    printf("%s x %ld, last err %02X\n", what, n, s.link.tx[4]);
    return 0;
}

static int bench_latency(void)
{
    static const uint8_t codes[] = {2, 4, 10}; /* 9600, 115200, 1792000 baud */
    for (unsigned k = 0; k < 3; k++) {
        static struct vbus b;
        vbus_init(&b);
        b.host_baud = 9600;
        vbus_add(&b, &board_foot, 1);
        struct servo *s = &b.node[0].servo;
        s->regs.mem[REG_RETURN_DELAY] = 0;
        s->regs.mem[REG_BAUD_RATE] = codes[k];
        link_latch(s);
        b.host_baud = s->link.baud;
        uint8_t raw[64];
        const char *names[] = {"PING", "READ 6", "WRITE 4"};
        for (int w = 0; w < 3; w++) {
            uint16_t len = w == 0   ? proto_build_packet(raw, 1, INS_PING, 0, 0)
                           : w == 1 ? proto_build_packet(raw, 1, INS_READ, read_params, sizeof read_params)
                                    : proto_build_packet(raw, 1, INS_WRITE, write_params,
                                             sizeof write_params);
            vbus_host_send(&b, raw, len);
            vbus_run_until(&b, b.now_us + 20000u);
            if (!vbus_host_pending(&b)) {
                printf("no answer\n");
                return 1;
            }
            const struct vbus_byte *first = vbus_host_next(&b);
            while (vbus_host_pending(&b))
                vbus_host_next(&b);
            printf("latency %-8s at %7u baud: %u us after the last request byte "
                   "(main loop period %u us)\n",
                   names[w], b.host_baud, first->start_us - b.last_host_end_us, b.step_us);
        }
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc >= 2 && strcmp(argv[1], "latency") == 0)
        return bench_latency();
    if (argc != 3) {
        fprintf(stderr, "usage: bench rx|read|write|sync N | bench latency\n");
        return 2;
    }
    long n = strtol(argv[2], 0, 10);
    if (strcmp(argv[1], "rx") == 0)
        return bench_rx(n);
    return bench_dispatch(argv[1], n);
}
