//! The exception model on real firmware (assembled with arm-none-eabi-as/ld): vector-table
//! boot, SVC, PendSV held off by PRIMASK, preemption by priority, SysTick, HardFault on an
//! undefined instruction with a handler that resumes, and a 44.1 kHz-style timer alarm
//! interrupt waking WFI, with per-function cycle accounting of the ISR.

mod common;

use tactus_emulator::{Board, Config, StopReason};
use tactus_isa::timing::{EXCEPTION_ENTRY, EXCEPTION_RETURN};

const LINK: [&str; 6] = [
    "--section-start=.vectors=0x20000000",
    "-Ttext=0x20000100",
    "-Tdata=0x20010000",
    "-e",
    "reset",
    "-N",
];

const PRELUDE: &str = r#"
.syntax unified
.cpu cortex-m0
.thumb
.section .vectors, "a"
.word 0x20042000
.word reset, nmi, hardfault, 0, 0, 0, 0, 0, 0, 0, svc_handler, 0, 0, pendsv, systick
.word timer_isr
.text
.macro log n
    ldr r0, =logp
    ldr r1, [r0]
    movs r2, #\n
    strb r2, [r1]
    adds r1, #1
    str r1, [r0]
.endm
.thumb_func
nmi: b nmi
"#;

fn build(name: &str, body: &str) -> Option<Vec<u8>> {
    if !common::have_tool("arm-none-eabi-as", name) || !common::have_tool("arm-none-eabi-ld", name)
    {
        return None;
    }
    let src = format!("{PRELUDE}{body}\n.ltorg\n.data\n.balign 4\nlogp: .word logbuf\ncount: .word 0\nlogbuf: .space 64\n");
    let dir = common::scratch_dir(name);
    let elf = common::assemble_and_link(&dir, name, &src, &LINK);
    Some(std::fs::read(elf).unwrap())
}

fn log(board: &mut Board) -> Vec<u8> {
    let start = board.symbol("logbuf").unwrap();
    let end = board.read_u32(board.symbol("logp").unwrap()).unwrap();
    let mut buf = vec![0; (end - start) as usize];
    board.read_bytes(start, &mut buf).unwrap();
    buf
}

#[test]
fn svc_pendsv_primask_priorities_systick_hardfault() {
    let Some(elf) = build(
        "exc",
        r#"
.thumb_func
reset:
    svc #0                  @ -> svc_handler logs 1
    cpsid i
    ldr r3, =0xe000ed04     @ ICSR
    ldr r4, =(1 << 28)      @ PENDSVSET
    str r4, [r3]
    log 2                   @ PendSV is pending but PRIMASK holds it off
    cpsie i                 @ -> pendsv logs 3 now
    log 4
    udf #7                  @ -> hardfault logs 5 and skips the UDF
    log 6
    ldr r3, =0xe000ed20     @ SHPR3: SysTick priority 3 (lowest), PendSV 0
    ldr r4, =0xc0000000
    str r4, [r3]
    ldr r3, =0xe000e010     @ SysTick: RVR = 999, CVR = 0, CSR = enable | tickint | clk
    ldr r4, =999
    str r4, [r3, #4]
    str r4, [r3, #8]
    movs r4, #7
    str r4, [r3]
1:  wfi
    ldr r0, =count
    ldr r0, [r0]
    cmp r0, #3
    bne 1b
    movs r4, #0
    str r4, [r3]            @ SysTick off
    log 9
2:  b 2b

.thumb_func
svc_handler:
    log 1
    bx lr

.thumb_func
pendsv:
    log 3
    bx lr

.thumb_func
hardfault:
    log 5
    ldr r0, [sp, #24]       @ stacked PC = the UDF
    adds r0, #2
    str r0, [sp, #24]
    bx lr

.thumb_func
systick:
    push {r4, lr}
    log 7
    ldr r0, =count
    ldr r1, [r0]
    adds r1, #1
    str r1, [r0]
    cmp r1, #1
    bne 3f
    ldr r3, =0xe000ed04     @ first tick: pend PendSV, which preempts (priority 0 < 3)
    ldr r4, =(1 << 28)
    str r4, [r3]
3:  log 8
    pop {r4, pc}

.thumb_func
timer_isr: b timer_isr
"#,
    ) else {
        return;
    };
    let mut board = Board::new(Config {
        stop_on_fault: false,
        ..Config::default()
    });
    board.load_elf(&elf).unwrap();
    assert_eq!(board.cores[0].r[13], 0x2004_2000, "SP from vector 0");
    let stop = board.run_for(20_000);
    assert_eq!(stop, StopReason::CycleLimit);
    assert_eq!(log(&mut board), [1, 2, 3, 4, 5, 6, 7, 3, 8, 7, 8, 7, 8, 9]);
    let c = &board.cores[0];
    assert_eq!(
        (c.ipsr, c.nvic.active, c.r[13]),
        (0, 0, 0x2004_2000),
        "all handlers returned, stack balanced"
    );
}

#[test]
fn timer_alarm_paces_sample_interrupt_and_function_cycles_are_measured() {
    let Some(elf) = build(
        "timer",
        r#"
.thumb_func
reset:
    ldr r0, =0x40054000     @ TIMER
    movs r1, #1
    str r1, [r0, #0x38]     @ INTE = alarm 0
    ldr r2, =0xe000e100
    str r1, [r2]            @ NVIC_ISER: IRQ 0
    ldr r1, [r0, #0x28]     @ TIMERAWL
    adds r1, #23
    str r1, [r0, #0x10]     @ ALARM0 = now + 23 us
1:  wfi
    b 1b

.thumb_func
timer_isr:
    ldr r0, =0x40054000
    movs r1, #1
    str r1, [r0, #0x34]     @ clear INTR
    ldr r1, [r0, #0x10]
    adds r1, #23
    str r1, [r0, #0x10]     @ next alarm, 23 us after the last one: no drift
    ldr r2, =count
    ldr r3, [r2]
    adds r3, #1
    str r3, [r2]
    bx lr

.thumb_func
hardfault: b hardfault
.thumb_func
svc_handler: b svc_handler
.thumb_func
pendsv: b pendsv
.thumb_func
systick: b systick
"#,
    ) else {
        return;
    };
    let mut board = Board::new(Config::default());
    board.load_elf(&elf).unwrap();
    let isr = board.profile("timer_isr").unwrap();
    // 1 ms at 133 MHz. Alarms fire at 23k us (k = 1..43 before 1000 us).
    assert_eq!(board.run_for(133_000), StopReason::CycleLimit);
    let count = board.read_u32(board.symbol("count").unwrap()).unwrap();
    assert_eq!(count, 1000 / 23);
    let calls = board.calls(isr);
    assert_eq!(calls.len(), count as usize);
    // ldr=2 movs=1 str(APB)=4 ldr(APB)=3 adds=1 str(APB)=4 ldr=2 ldr=2 adds=1 str=2 bx=2,
    // plus the exception return.
    let body = 2 + 1 + 4 + 3 + 1 + 4 + 2 + 2 + 1 + 2 + 2;
    for call in calls {
        assert_eq!(call.cycles, body + EXCEPTION_RETURN as u64, "{call:?}");
    }
    // Each ISR starts EXCEPTION_ENTRY cycles after the alarm's cycle (the core sleeps in
    // WFI, so it wakes exactly then): alarm k fires at 23k us * 133 cycles/us.
    for (k, call) in calls.iter().enumerate() {
        let fire = 23 * (k as u64 + 1) * 133;
        assert_eq!(call.start, fire + EXCEPTION_ENTRY as u64, "call {k}");
    }
}
