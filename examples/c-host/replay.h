/* Replay of the firmware-qemu golden trajectory through the fogtemp C ABI.
 * Shared by examples/c-host (x86_64, system cc) and examples/c-firmware-qemu (Cortex-M4F). */
#ifndef FOGTEMP_REPLAY_H
#define FOGTEMP_REPLAY_H

#include <stddef.h>
#include <stdint.h>

/* Where output lines go (one line per call, no trailing newline). */
typedef void (*replay_emit)(const char *line);

/* The flash partition (blob + erased 0xFF) and the trajectory records
 * (u64 time_us, f32 gyro_dph, f32 temp_c little-endian; NaN = no temperature).
 * Prints `out`, `digest`, `wrap` and `done` lines in the grammar of
 * examples/firmware-qemu/README.md. Returns 0 on success, 1 on any failure. */
/* Optional cycle source for the cost report (a down-counting timer); NULL (the default)
 * for none. When set, the u64 replay times every fogtemp_step call and prints a `cost` line:
 * calls, total and largest ticks, and the record of the largest. */
void fogtemp_replay_set_clock(uint32_t (*down_counter)(void));

int fogtemp_replay(const uint8_t *partition, size_t partition_len, const uint8_t *trajectory,
                   size_t trajectory_len, replay_emit emit);

#endif
