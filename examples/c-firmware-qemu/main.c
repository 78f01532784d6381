/* C firmware for the Cortex-M4F (QEMU mps2-an386): the golden-trajectory replay of
 * examples/c-host/replay.c linked with the thumbv7em-none-eabihf libfogtemp_ffi.a. Output
 * through Arm semihosting (SYS_WRITE0), buffered; exit through SYS_EXIT. */
#include <stdint.h>
#include <string.h>

#include "replay.h"

extern const uint8_t fogtemp_partition[], fogtemp_partition_end[];
extern const uint8_t fogtemp_trajectory[], fogtemp_trajectory_end[];
uint32_t stack_used_bytes(void);

static int semihost(int op, const void *arg) {
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void semihost_exit(int ok) {
    /* ADP_Stopped_ApplicationExit (QEMU exits 0) or ADP_Stopped_RunTimeErrorUnknown (exits 1). */
    semihost(0x18, (const void *)(uintptr_t)(ok ? 0x20026 : 0x20023));
    for (;;) __asm volatile("wfi");
}

static char out_buf[2048];
static size_t out_len;

static void flush(void) {
    if (out_len) {
        out_buf[out_len] = 0;
        semihost(0x04, out_buf); /* SYS_WRITE0 */
        out_len = 0;
    }
}

static void emit(const char *line) {
    size_t n = strlen(line);
    if (out_len + n + 2 > sizeof out_buf) flush();
    memcpy(out_buf + out_len, line, n);
    out_len += n;
    out_buf[out_len++] = '\n';
}

#ifdef BASELINE
/* The same harness without the runtime (only built to measure the runtime's size by
 * difference): pass-through of every record, no fogtemp call, no model. */
static int replay_baseline(void) {
    size_t n = (size_t)(fogtemp_trajectory_end - fogtemp_trajectory) / 16;
    uint64_t digest = 0xcbf29ce484222325ULL;
    for (size_t i = 0; i < n; i++) {
        digest ^= fogtemp_trajectory[i * 16 + 8];
        digest *= 0x00000100000001b3ULL;
    }
    emit(digest ? "done baseline" : "done baseline 0");
    return 0;
}
#endif

/* CMSDK APB timer 0 of mps2-an386 (0x4000_0000), counting down at the 25 MHz system clock.
 * Under `qemu -icount shift=0` every guest instruction advances virtual time by 1 ns, so a
 * tick is 40 instructions (calibrated below against a loop of known length). */
#ifndef BASELINE
#define TIMER0_CTRL (*(volatile uint32_t *)0x40000000u)
#define TIMER0_VALUE (*(volatile uint32_t *)0x40000004u)
#define TIMER0_RELOAD (*(volatile uint32_t *)0x40000008u)
static uint32_t timer0(void) { return TIMER0_VALUE; }

/* 2 instructions per iteration (subs, bne), plus a few. */
static uint32_t calibrate(uint32_t iterations) {
    uint32_t t0 = timer0();
    __asm volatile("1: subs %0, %0, #1\n bne 1b" : "+r"(iterations)::"cc");
    return t0 - timer0();
}
#endif

static char *put_u32(char *p, uint32_t v) {
    char tmp[12];
    int n = 0;
    do { tmp[n++] = (char)('0' + v % 10); v /= 10; } while (v);
    while (n) *p++ = tmp[--n];
    return p;
}

int main(void) {
    emit("fogtemp c-firmware-qemu: start");
#ifdef BASELINE
    int status = replay_baseline();
#else
    TIMER0_RELOAD = 0xFFFFFFFFu;
    TIMER0_VALUE = 0xFFFFFFFFu;
    TIMER0_CTRL = 1u; /* enable, system clock */
    {
        char cal[64];
        char *q = cal;
        memcpy(q, "clock ticks for 2000000 loop instructions=", 42);
        q = put_u32(q + 42, calibrate(1000000u));
        *q = 0;
        emit(cal);
    }
    fogtemp_replay_set_clock(timer0);
    int status = fogtemp_replay(fogtemp_partition, (size_t)(fogtemp_partition_end - fogtemp_partition),
                                fogtemp_trajectory, (size_t)(fogtemp_trajectory_end - fogtemp_trajectory), emit);
#endif
    char line[48];
    char *p = line;
    memcpy(p, "stack used=", 11);
    p = put_u32(p + 11, stack_used_bytes());
    *p = 0;
    emit(line);
    flush();
    return status;
}
