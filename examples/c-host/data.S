/* The golden model and trajectory of examples/firmware-qemu, linked in as data.
 * The model sits in a 64 KiB "flash partition": the blob, then erased flash (0xFF),
 * read with fogtemp_model_from_flash. Paths are given by -DMODEL_PATH / -DTRAJ_PATH. */
    .section .rodata.fogtemp_partition, "a"
    .balign 4
    .global fogtemp_partition
fogtemp_partition:
    .incbin MODEL_PATH
fogtemp_partition_model_end:
    .fill 65536 - (fogtemp_partition_model_end - fogtemp_partition), 1, 0xff
    .global fogtemp_partition_end
fogtemp_partition_end:

    .section .rodata.fogtemp_trajectory, "a"
    .balign 8
    .global fogtemp_trajectory
fogtemp_trajectory:
    .incbin TRAJ_PATH
    .global fogtemp_trajectory_end
fogtemp_trajectory_end:

#if defined(__ELF__)
    .section .note.GNU-stack, "", %progbits  /* no executable stack */
#endif
