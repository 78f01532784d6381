/* Bare-metal start for the Cortex-M4F on QEMU mps2-an386: vector table, .data/.bss set-up,
 * stack painting (to measure the peak), FPU on, main, then semihosting SYS_EXIT. */
#include <stdint.h>
#include <string.h>

extern uint32_t _sidata[], _sdata[], _edata[], _sbss[], _ebss[], _sstack[], _estack[];
extern int main(void);
void reset_handler(void);
void fault_handler(void);
void semihost_exit(int ok);

#define STACK_PAINT 0xC0FFEE55u

__attribute__((section(".vector_table"), used)) static const void *const vector_table[16] = {
    _estack, reset_handler, fault_handler, fault_handler, fault_handler, fault_handler, fault_handler,
};

void fault_handler(void) { semihost_exit(0); }

/* Bytes of stack ever used (deepest word no longer painted). */
uint32_t stack_used_bytes(void) {
    uint32_t *p = _sstack;
    while (p < _estack && *p == STACK_PAINT) p++;
    return (uint32_t)((uintptr_t)_estack - (uintptr_t)p);
}

__attribute__((naked)) void reset_handler(void) {
    __asm volatile(
        /* Paint the stack below the current SP (the reset SP is _estack). */
        "ldr r0, =_sstack\n"
        "mov r1, sp\n"
        "ldr r2, =0xC0FFEE55\n"
        "1: cmp r0, r1\n"
        "bhs 2f\n"
        "str r2, [r0], #4\n"
        "b 1b\n"
        "2: b reset_c\n");
}

__attribute__((used)) void reset_c(void) {
    memcpy(_sdata, _sidata, (size_t)((uintptr_t)_edata - (uintptr_t)_sdata));
    memset(_sbss, 0, (size_t)((uintptr_t)_ebss - (uintptr_t)_sbss));
    /* CPACR: full access to CP10/CP11 (the single-precision FPU). */
    volatile uint32_t *cpacr = (volatile uint32_t *)0xE000ED88u;
    *cpacr |= 0xFu << 20;
    __asm volatile("dsb\n isb" ::: "memory");
    semihost_exit(main() == 0);
}
