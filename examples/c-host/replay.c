/* Replay of the firmware-qemu golden trajectory through the fogtemp C ABI (see replay.h).
 *
 * 1. checks the header's struct sizes against the library (fogtemp_layout);
 * 2. reads the model from a flash partition (blob followed by erased 0xFF bytes);
 * 3. shows the capacity contract: a blocks array one short is refused, naming both numbers;
 * 4. replays every record with fogtemp_step (u64 microseconds) and prints the same `out`
 *    and `digest` lines as the Rust firmware (compared with data/expected_out.txt);
 * 5. resets the state and replays again with fogtemp_step_u32, the times shifted so the
 *    32-bit microsecond timer wraps in the middle: the digest must be the same. */
#include "replay.h"

#include <string.h>

#include "fogtemp.h"

#define RECORD_LEN 16
#define PRINT_STRIDE 20
/* Room for the tracker's block means: the model says how many it needs
 * (fogtemp_axis_blocks_needed); a model needing more is refused at init. */
#define BLOCKS_CAPACITY 64

static fogtemp_model model;
static fogtemp_axis axis;
static fogtemp_state state;
static float blocks[BLOCKS_CAPACITY];

static char line[160];
static uint32_t (*clock_fn)(void);

void fogtemp_replay_set_clock(uint32_t (*down_counter)(void)) { clock_fn = down_counter; }

/* Tiny formatting (no printf: the firmware has no stdio). */
static char *put_str(char *p, const char *s) {
    while (*s) *p++ = *s++;
    return p;
}
static char *put_u64(char *p, uint64_t v) {
    char tmp[24];
    int n = 0;
    do { tmp[n++] = (char)('0' + v % 10); v /= 10; } while (v);
    while (n) *p++ = tmp[--n];
    return p;
}
static char *put_hex(char *p, uint64_t v, int digits) {
    static const char hex[] = "0123456789abcdef";
    for (int i = digits - 1; i >= 0; i--) *p++ = hex[(v >> (4 * i)) & 0xf];
    return p;
}

static uint32_t f32_bits(float f) {
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static uint64_t fnv1a(uint64_t h, uint32_t v, int n) {
    for (int i = 0; i < n; i++) {
        h ^= (v >> (8 * i)) & 0xff;
        h *= 0x00000100000001b3ULL;
    }
    return h;
}

static void record(const uint8_t *r, uint64_t *time_us, float *gyro_dph, float *temp_c) {
    memcpy(time_us, r, 8); /* little-endian on both targets */
    memcpy(gyro_dph, r + 8, 4);
    memcpy(temp_c, r + 12, 4);
}

static int fail(replay_emit emit, const char *what, fogtemp_status s, const fogtemp_error *err) {
    char *p = put_str(line, "error ");
    p = put_str(p, what);
    p = put_str(p, ": ");
    p = put_str(p, fogtemp_status_message(s));
    if (err) {
        p = put_str(p, ": ");
        size_t room = (size_t)(line + sizeof line - p);
        size_t n = fogtemp_error_message(err, p, room);
        p += n < room ? n : room - 1;
    }
    *p = 0;
    emit(line);
    return 1;
}

int fogtemp_replay(const uint8_t *partition, size_t partition_len, const uint8_t *trajectory,
                   size_t trajectory_len, replay_emit emit) {
    fogtemp_error err;
    fogtemp_status s;
    char *p;

    size_t layout[8];
    s = fogtemp_layout(&layout);
    if (s != FOGTEMP_STATUS_OK || layout[0] != sizeof(fogtemp_model) || layout[2] != sizeof(fogtemp_axis) ||
        layout[4] != sizeof(fogtemp_state) || layout[6] != sizeof(fogtemp_error)) {
        return fail(emit, "layout (header and library disagree)", s, NULL);
    }

    size_t used = 0, axes = 0, needed = 0;
    s = fogtemp_model_from_flash(partition, partition_len, &model, &used, &err);
    if (s != FOGTEMP_STATUS_OK) return fail(emit, "fogtemp_model_from_flash", s, &err);
    fogtemp_model_axis_count(&model, &axes);
    s = fogtemp_model_axis(&model, 0, &axis, &err);
    if (s != FOGTEMP_STATUS_OK) return fail(emit, "fogtemp_model_axis", s, &err);
    fogtemp_axis_blocks_needed(&axis, &needed);
    p = put_str(line, "model partition=");
    p = put_u64(p, partition_len);
    p = put_str(p, " used=");
    p = put_u64(p, used);
    p = put_str(p, " axes=");
    p = put_u64(p, axes);
    p = put_str(p, " blocks_needed=");
    p = put_u64(p, needed);
    p = put_str(p, " state_bytes=");
    p = put_u64(p, sizeof state + needed * sizeof(float));
    *p = 0;
    emit(line);

    /* The capacity contract: one block short is refused with both numbers. */
    s = fogtemp_state_init(&axis, &state, blocks, needed - 1, &err);
    if (s != FOGTEMP_STATUS_CAPACITY_TOO_SMALL || err.needed != needed || err.found != needed - 1) {
        return fail(emit, "capacity check (expected CAPACITY_TOO_SMALL)", s, NULL);
    }
    p = put_str(line, "capacity refused: ");
    p += fogtemp_error_message(&err, p, (size_t)(line + sizeof line - p));
    *p = 0;
    emit(line);
    s = fogtemp_state_init(&axis, &state, blocks, BLOCKS_CAPACITY, &err);
    if (s != FOGTEMP_STATUS_OK) return fail(emit, "fogtemp_state_init", s, &err);

    if (trajectory_len % RECORD_LEN != 0) return fail(emit, "trajectory length", FOGTEMP_STATUS_OTHER, NULL);
    size_t records = trajectory_len / RECORD_LEN;
    uint64_t digest = 0xcbf29ce484222325ULL;
    size_t printed = 0;
    uint32_t prev_bias = 0;
    uint64_t cost_total = 0;
    uint32_t cost_max = 0;
    size_t cost_max_at = 0;
    int prev_flags = -1;
    for (size_t i = 0; i < records; i++) {
        uint64_t t;
        float gyro, temp;
        fogtemp_output o;
        record(trajectory + i * RECORD_LEN, &t, &gyro, &temp);
        uint32_t c0 = clock_fn ? clock_fn() : 0;
        s = fogtemp_step(&axis, &state, t, gyro, temp, temp == temp /* not NaN */, &o);
        if (clock_fn) {
            uint32_t ticks = c0 - clock_fn();
            cost_total += ticks;
            if (ticks > cost_max) { cost_max = ticks; cost_max_at = i; }
        }
        if (s != FOGTEMP_STATUS_OK) return fail(emit, "fogtemp_step", s, NULL);
        uint32_t rate = f32_bits(o.rate_dph), bias = f32_bits(o.bias_dph);
        digest = fnv1a(fnv1a(fnv1a(digest, rate, 4), bias, 4), o.flags, 1);
        if (prev_flags != o.flags || prev_bias != bias || i % PRINT_STRIDE == 0 || i + 1 == records) {
            p = put_str(line, "out ");
            p = put_u64(p, i);
            *p++ = ' ';
            p = put_hex(p, rate, 8);
            *p++ = ' ';
            p = put_hex(p, bias, 8);
            *p++ = ' ';
            p = put_hex(p, o.flags, 2);
            *p = 0;
            emit(line);
            printed++;
        }
        prev_bias = bias;
        prev_flags = o.flags;
    }
    p = put_str(line, "digest ");
    p = put_u64(p, records);
    *p++ = ' ';
    p = put_hex(p, digest, 16);
    *p = 0;
    emit(line);

    if (clock_fn) {
        p = put_str(line, "cost fogtemp_step calls=");
        p = put_u64(p, records);
        p = put_str(p, " ticks=");
        p = put_u64(p, cost_total);
        p = put_str(p, " max_ticks=");
        p = put_u64(p, cost_max);
        p = put_str(p, " at record ");
        p = put_u64(p, cost_max_at);
        *p = 0;
        emit(line);
    }

    /* Again after a reset, with a wrapping 32-bit timer that wraps 100 s into the run. */
    s = fogtemp_state_reset(&state);
    if (s != FOGTEMP_STATUS_OK) return fail(emit, "fogtemp_state_reset", s, NULL);
    uint64_t t0;
    float unused_g, unused_c;
    record(trajectory, &t0, &unused_g, &unused_c);
    uint64_t offset = (1ULL << 32) - 100000000ULL - t0;
    uint64_t digest32 = 0xcbf29ce484222325ULL;
    size_t wrapped_at = 0;
    for (size_t i = 0; i < records; i++) {
        uint64_t t;
        float gyro, temp;
        fogtemp_output o;
        record(trajectory + i * RECORD_LEN, &t, &gyro, &temp);
        uint32_t t32 = (uint32_t)(t + offset);
        if (!wrapped_at && t + offset >= (1ULL << 32)) wrapped_at = i;
        s = fogtemp_step_u32(&axis, &state, t32, gyro, temp, temp == temp, &o);
        if (s != FOGTEMP_STATUS_OK) return fail(emit, "fogtemp_step_u32", s, NULL);
        digest32 = fnv1a(fnv1a(fnv1a(digest32, f32_bits(o.rate_dph), 4), f32_bits(o.bias_dph), 4), o.flags, 1);
    }
    p = put_str(line, "wrap step_u32 wraps at record ");
    p = put_u64(p, wrapped_at);
    p = put_str(p, ", digest ");
    p = put_hex(p, digest32, 16);
    p = put_str(p, digest32 == digest ? " equal to step (u64)" : " DIFFERS from step (u64)");
    *p = 0;
    emit(line);
    if (digest32 != digest) return 1;

    p = put_str(line, "done records=");
    p = put_u64(p, records);
    p = put_str(p, " printed=");
    p = put_u64(p, printed);
    *p = 0;
    emit(line);
    return 0;
}
