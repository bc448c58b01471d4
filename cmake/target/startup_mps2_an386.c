/*
 * Minimal start-up for the on-target tests on QEMU mps2-an386 (Cortex-M4F, fpv4-sp-d16).
 *
 * Reset: enable the FPU (CPACR CP10/CP11 full access) before any floating-point instruction,
 * copy .data from its load image, zero .bss, open the semihosting stdio handles (newlib rdimon),
 * run main() and exit() with its return value. exit() flushes stdio and ends in _exit, which the
 * link wraps (-Wl,--wrap=_exit) to issue SYS_EXIT_EXTENDED so QEMU's exit status is the real
 * code: newlib's own _exit may use plain SYS_EXIT, which QEMU always maps to 0.
 * Every fault vector prints a message and exits with MAGCAL_TARGET_FAULT_EXIT.
 *
 * Test infrastructure only (cmake/target/); never linked into the library.
 */
#include <stdint.h>
#include <stdlib.h>

#define MAGCAL_TARGET_FAULT_EXIT 3

/* Semihosting operations (ARM "Semihosting for AArch32 and AArch64", v2). */
#define SEMIHOST_SYS_WRITE0 0x04u
#define SEMIHOST_SYS_EXIT 0x18u
#define SEMIHOST_SYS_EXIT_EXTENDED 0x20u
#define SEMIHOST_ADP_STOPPED_APPLICATION_EXIT 0x20026u

extern uint32_t __data_load;
extern uint32_t __data_start;
extern uint32_t __data_end;
extern uint32_t __bss_start__;
extern uint32_t __bss_end__;
extern uint32_t __stack_top;

extern int main(void);
extern void initialise_monitor_handles(void);
extern void __libc_init_array(void);

/* -nostartfiles drops crti.o/crtn.o, which would supply these two for __libc_{init,fini}_array;
 * the tests have no .init/.fini code of their own. */
void _init(void);
void _fini(void);
void _init(void) {}
void _fini(void) {}

void Reset_Handler(void);
void magcal_target_reset_c(void);
void magcal_target_fault(void);
void __wrap__exit(int code);

static uintptr_t semihost_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return (uintptr_t)r0;
}

/* Real exit: SYS_EXIT_EXTENDED carries the status. A code that is a multiple of 256 would read
 * as 0 on the host, so any non-zero code is forced into 1..255. */
void __wrap__exit(int code)
{
    uint32_t block[2];
    uint32_t c = (uint32_t)code;
    if (c != 0u && (c & 0xFFu) == 0u) {
        c = 1u;
    }
    block[0] = SEMIHOST_ADP_STOPPED_APPLICATION_EXIT;
    block[1] = c;
    (void)semihost_call(SEMIHOST_SYS_EXIT_EXTENDED, block);
    /* Only reached if the debugger ignored the request. */
    for (;;) {
        (void)semihost_call(SEMIHOST_SYS_EXIT, (const void *)SEMIHOST_ADP_STOPPED_APPLICATION_EXIT);
    }
}

/* HardFault and every other unexpected exception: report and fail the test run. No stdio here,
 * the fault may have come from inside it. */
void magcal_target_fault(void)
{
    (void)semihost_call(SEMIHOST_SYS_WRITE0,
                        "\n*** magcal target: unexpected exception (fault) ***\n");
    __wrap__exit(MAGCAL_TARGET_FAULT_EXIT);
}

void magcal_target_reset_c(void)
{
    const uint32_t *src = &__data_load;
    uint32_t *dst;
    for (dst = &__data_start; dst < &__data_end; ++dst) {
        *dst = *src++;
    }
    for (dst = &__bss_start__; dst < &__bss_end__; ++dst) {
        *dst = 0u;
    }
    initialise_monitor_handles();
    __libc_init_array();
    exit(main());
}

/* Naked so that no compiler-generated code (which might touch an FP register) runs before the
 * FPU is enabled: CPACR (0xE000ED88) |= 0xF << 20, then DSB/ISB before the first VFP op. */
__attribute__((naked, noreturn)) void Reset_Handler(void)
{
    __asm__ volatile("ldr r0, =0xE000ED88\n"
                     "ldr r1, [r0]\n"
                     "orr r1, r1, #(0xF << 20)\n"
                     "str r1, [r0]\n"
                     "dsb\n"
                     "isb\n"
                     "b magcal_target_reset_c\n");
}

typedef void (*magcal_vector_t)(void);

/* Cortex-M vector table: initial SP, reset, then the system exceptions. Interrupts are never
 * enabled by the tests, so the external IRQ entries are omitted. */
__attribute__((section(".isr_vector"), used)) static const magcal_vector_t g_vectors[16] = {
    (magcal_vector_t)(uintptr_t)&__stack_top, /* initial main stack pointer */
    Reset_Handler,
    magcal_target_fault, /* NMI */
    magcal_target_fault, /* HardFault */
    magcal_target_fault, /* MemManage */
    magcal_target_fault, /* BusFault */
    magcal_target_fault, /* UsageFault */
    0,                   /* reserved */
    0,                   /* reserved */
    0,                   /* reserved */
    0,                   /* reserved */
    magcal_target_fault, /* SVCall */
    magcal_target_fault, /* DebugMonitor */
    0,                   /* reserved */
    magcal_target_fault, /* PendSV */
    magcal_target_fault, /* SysTick */
};
