/* Host replay of the golden trajectory through the fogtemp C ABI (static library). */
#include <stdio.h>

#include "replay.h"

extern const uint8_t fogtemp_partition[], fogtemp_partition_end[];
extern const uint8_t fogtemp_trajectory[], fogtemp_trajectory_end[];

static void emit(const char *line) { puts(line); }

int main(void) {
    return fogtemp_replay(fogtemp_partition, (size_t)(fogtemp_partition_end - fogtemp_partition),
                          fogtemp_trajectory, (size_t)(fogtemp_trajectory_end - fogtemp_trajectory), emit);
}
