//! The static WCET analysis against the cycle-accurate board: code built with the encoder,
//! every path driven by inputs through `Board::call`, static == measured on the worst path
//! and static ≥ measured on every path.

use std::collections::HashMap;
use tactus_emulator::{Board, Config};
use tactus_isa::decode::{AluOp, Instr, MemOp};
use tactus_isa::encode::encode;
use tactus_isa::timing::{EXCEPTION_ENTRY, EXCEPTION_RETURN};
use tactus_isa::wcet::{analyse, analyse_isr, Bounds, Image, Region, WcetError};

const BASE: u32 = 0x2000_0000;
const SP: u32 = 0x2004_0000;

/// Condition codes.
const EQ: u8 = 0;
const NE: u8 = 1;
const CS: u8 = 2;
const CC: u8 = 3;
const GT: u8 = 12;
const LE: u8 = 13;

/// One item of a tiny assembler: instructions, labels, label-relative branches, literals.
#[derive(Clone, Debug)]
enum It {
    I(Instr),
    L(String),
    B(String),
    Bc(u8, String),
    Bl(String),
    /// `LDR rt, =label_of_word` — a literal load from the word at the label.
    Lit(u8, String),
    /// Align to 4 with a NOP-free padding halfword (0x0000 is `MOVS r0, r0`; it is data here).
    Align,
    Word(u32),
}

use It::*;

fn l(s: &str) -> It {
    L(s.to_string())
}
fn b(s: &str) -> It {
    B(s.to_string())
}
fn bc(c: u8, s: &str) -> It {
    Bc(c, s.to_string())
}
fn bl(s: &str) -> It {
    Bl(s.to_string())
}
fn movs(rd: u8, imm: u8) -> It {
    I(Instr::MovImm { rd, imm })
}
fn adds(rd: u8, rn: u8, imm: u8) -> It {
    I(Instr::AddImm { rd, rn, imm })
}
fn subs(rd: u8, rn: u8, imm: u8) -> It {
    I(Instr::SubImm { rd, rn, imm })
}
fn cmpi(rn: u8, imm: u8) -> It {
    I(Instr::CmpImm { rn, imm })
}
fn alu(op: AluOp, rdn: u8, rm: u8) -> It {
    I(Instr::Alu { op, rdn, rm })
}
fn bx_lr() -> It {
    I(Instr::Bx { rm: 14 })
}
fn nop() -> It {
    I(Instr::Hint(tactus_isa::decode::Hint::Nop))
}

fn size(it: &It, addr: u32) -> u32 {
    match it {
        I(x) => encode(x).unwrap().bytes().len() as u32,
        L(_) => 0,
        B(_) | Bc(..) | Lit(..) => 2,
        Bl(_) => 4,
        Align => addr % 4,
        Word(_) => 4,
    }
}

/// Assembles at `base`: the bytes and the label addresses.
fn assemble(base: u32, items: &[It]) -> (Vec<u8>, HashMap<String, u32>) {
    let mut labels = HashMap::new();
    let mut addr = base;
    for it in items {
        if let L(s) = it {
            assert!(labels.insert(s.clone(), addr).is_none(), "label {s} twice");
        }
        addr += size(it, addr);
    }
    let mut out = Vec::new();
    let mut addr = base;
    for it in items {
        let rel = |s: &String| labels[s] as i32 - (addr as i32 + 4);
        let bytes = match it {
            I(x) => encode(x).unwrap().bytes(),
            L(_) => vec![],
            B(s) => encode(&Instr::B { offset: rel(s) }).unwrap().bytes(),
            Bc(c, s) => encode(&Instr::BCond {
                cond: *c,
                offset: rel(s),
            })
            .unwrap()
            .bytes(),
            Bl(s) => encode(&Instr::Bl { offset: rel(s) }).unwrap().bytes(),
            Lit(rt, s) => {
                let imm = labels[s] - ((addr + 4) & !3);
                encode(&Instr::LdrLit {
                    rt: *rt,
                    imm: imm as u16,
                })
                .unwrap()
                .bytes()
            }
            Align => vec![0; (addr % 4) as usize],
            Word(w) => w.to_le_bytes().to_vec(),
        };
        assert_eq!(bytes.len() as u32, size(it, addr));
        addr += bytes.len() as u32;
        out.extend(bytes);
    }
    (out, labels)
}

struct Prog {
    bytes: Vec<u8>,
    labels: HashMap<String, u32>,
    board: Board,
}

impl Prog {
    fn new(items: &[It]) -> Prog {
        let (bytes, labels) = assemble(BASE, items);
        let mut board = Board::new(Config::default());
        board.write_bytes(BASE, &bytes).unwrap();
        Prog {
            bytes,
            labels,
            board,
        }
    }
    fn at(&self, label: &str) -> u32 {
        self.labels[label]
    }
    fn wcet(&self, entry: &str, bounds: &Bounds) -> Result<tactus_isa::wcet::Wcet, WcetError> {
        analyse(
            &Image {
                base: BASE,
                bytes: &self.bytes,
            },
            self.at(entry),
            bounds,
        )
    }
    fn run(&mut self, entry: &str, args: &[u32]) -> u64 {
        let at = self.at(entry);
        match self.board.call(0, at, args, SP, 1_000_000) {
            Ok(r) => r.cycles,
            Err(e) => panic!("{e} with {args:?}: {:#x?}", self.labels),
        }
    }
    /// Static WCET vs. measurements over `inputs`: static ≥ every run, == the slowest.
    fn check(&mut self, entry: &str, bounds: &Bounds, inputs: &[Vec<u32>]) -> u64 {
        let w = self.wcet(entry, bounds).unwrap();
        let measured: Vec<u64> = inputs.iter().map(|a| self.run(entry, a)).collect();
        for (a, m) in inputs.iter().zip(&measured) {
            assert!(
                w.cycles >= *m,
                "static {} < measured {m} for {a:?}",
                w.cycles
            );
        }
        assert_eq!(
            w.cycles,
            *measured.iter().max().unwrap(),
            "static vs worst measured {measured:?}"
        );
        w.cycles
    }
}

#[test]
fn straight_line() {
    let mut p = Prog::new(&[
        l("f"),
        I(Instr::Push { list: 0x40f0 }), // push {r4-r7, lr}: 6
        movs(1, 7),                      // 1
        adds(0, 0, 3),                   // 1
        alu(AluOp::Mul, 0, 1),           // 1
        I(Instr::SubSp { imm: 8 }),      // 1
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 0,
            rn: 13,
            imm: 4,
        }), // 2
        I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: 2,
            rn: 13,
            imm: 4,
        }), // 2
        I(Instr::AddSp { imm: 8 }),      // 1
        I(Instr::Pop { list: 0x80f0 }),  // pop {r4-r7, pc}: 3 + 4
    ]);
    let c = p.check("f", &Bounds::new(), &[vec![1], vec![100]]);
    assert_eq!(c, 6 + 1 + 1 + 1 + 1 + 2 + 2 + 1 + 7);
    let w = p.wcet("f", &Bounds::new()).unwrap();
    assert_eq!(w.path, vec![p.at("f")]);
    assert_eq!(w.blocks.len(), 1);
    // As an exception handler: entry and return on top.
    let image = Image {
        base: BASE,
        bytes: &p.bytes,
    };
    let isr = analyse_isr(&image, p.at("f"), &Bounds::new()).unwrap();
    assert_eq!(
        isr.cycles,
        c + EXCEPTION_ENTRY as u64 + EXCEPTION_RETURN as u64
    );
}

#[test]
fn diamond_with_unequal_arms() {
    let mut p = Prog::new(&[
        l("f"),
        cmpi(0, 0),
        bc(EQ, "else"),
        l("then"),
        adds(1, 1, 1),
        adds(1, 1, 2),
        b("end"),
        l("else"),
        movs(1, 0),
        adds(1, 1, 1),
        adds(1, 1, 1),
        adds(1, 1, 1),
        adds(1, 1, 1),
        adds(1, 1, 1),
        l("end"),
        I(Instr::MovHi { rd: 0, rm: 1 }),
        bx_lr(),
    ]);
    // then: 1 + 1 (not taken) + 2 + 2 (B) + 1 + 2 = 9; else: 1 + 2 + 6 + 1 + 2 = 12.
    assert_eq!(p.run("f", &[1]), 9);
    let c = p.check("f", &Bounds::new(), &[vec![0], vec![1], vec![7]]);
    assert_eq!(c, 12);
    let w = p.wcet("f", &Bounds::new()).unwrap();
    assert_eq!(w.path, vec![p.at("f"), p.at("else"), p.at("end")]);

    // Swap which arm is long: now the not-taken arm is the worst one.
    let mut p = Prog::new(&[
        l("f"),
        cmpi(0, 0),
        bc(NE, "short"),
        adds(1, 1, 1),
        adds(1, 1, 1),
        adds(1, 1, 1),
        adds(1, 1, 1),
        b("end"),
        l("short"),
        nop(),
        l("end"),
        bx_lr(),
    ]);
    let c = p.check("f", &Bounds::new(), &[vec![0], vec![3]]);
    assert_eq!(c, 1 + 1 + 4 + 2 + 2);
    let w = p.wcet("f", &Bounds::new()).unwrap();
    assert_eq!(w.path, vec![p.at("f"), w.blocks[1].start, p.at("end")]);
}

#[test]
fn nested_branches() {
    let mut p = Prog::new(&[
        l("f"),
        cmpi(0, 0),
        bc(EQ, "a0"),
        cmpi(1, 0),
        bc(EQ, "b0"),
        adds(2, 2, 1),
        b("join"),
        l("b0"),
        alu(AluOp::Mul, 2, 2),
        alu(AluOp::Mul, 2, 2),
        alu(AluOp::Mul, 2, 2),
        b("join"),
        l("a0"),
        cmpi(1, 5),
        bc(GT, "c1"),
        adds(2, 2, 1),
        adds(2, 2, 1),
        l("c1"),
        adds(2, 2, 1),
        l("join"),
        I(Instr::Push { list: 0x4000 }),
        I(Instr::Pop { list: 0x8000 }),
    ]);
    let inputs: Vec<Vec<u32>> = [(0, 0), (0, 9), (1, 0), (1, 1), (3, 7)]
        .iter()
        .map(|&(a, b)| vec![a, b, 3])
        .collect();
    p.check("f", &Bounds::new(), &inputs);
}

#[test]
fn counted_loop_with_bound() {
    // r2 = 0; do { r2 += 1; r1 += r2 } while (r2 != r0); header executes r0 times.
    let items = vec![
        l("f"),
        movs(2, 0),
        movs(1, 0),
        l("loop"),
        adds(2, 2, 1),
        I(Instr::AddReg {
            rd: 1,
            rn: 1,
            rm: 2,
        }),
        alu(AluOp::Cmp, 2, 0),
        bc(NE, "loop"),
        I(Instr::MovHi { rd: 0, rm: 1 }),
        bx_lr(),
    ];
    let mut p = Prog::new(&items);
    let header = p.at("loop");
    for n in [1u32, 2, 5, 10] {
        let bounds = Bounds::new().with_loop(header, n);
        let inputs: Vec<Vec<u32>> = (1..=n).map(|k| vec![k]).collect();
        let c = p.check("f", &bounds, &inputs);
        // 2 + n × 3 + (n − 1) × 2 (taken) + 1 (not taken) + 1 + 2
        assert_eq!(c, 2 + 3 * n as u64 + 2 * (n as u64 - 1) + 1 + 3);
        let w = p.wcet("f", &bounds).unwrap();
        assert_eq!(w.path.len(), 2 + n as usize);
        assert_eq!(w.path.iter().filter(|&&a| a == header).count(), n as usize);
    }
    // Without a bound: an error naming the header.
    let e = p.wcet("f", &Bounds::new()).unwrap_err();
    assert_eq!(e, WcetError::UnboundedLoop { header });
    assert!(e.to_string().contains(&format!("{header:#010x}")));
    assert_eq!(
        p.wcet("f", &Bounds::new().with_loop(header, 0))
            .unwrap_err(),
        WcetError::ZeroBound { header }
    );
}

#[test]
fn loop_with_test_at_top_and_branch_inside() {
    // while (r0 != 0) { if (r0 & 1) { long } else { short }; r0 -= 1 } — header runs r0 + 1 times.
    let mut p = Prog::new(&[
        l("f"),
        movs(3, 1),
        l("head"),
        cmpi(0, 0),
        bc(EQ, "out"),
        I(Instr::MovHi { rd: 2, rm: 0 }),
        alu(AluOp::And, 2, 3),
        bc(EQ, "even"),
        adds(1, 1, 1),
        adds(1, 1, 1),
        adds(1, 1, 1),
        adds(1, 1, 1),
        l("even"),
        subs(0, 0, 1),
        b("head"),
        l("out"),
        bx_lr(),
    ]);
    let head = p.at("head");
    // With a bound of 4 the worst case runs three iterations, all on the long arm: no
    // input does that (odd, even, odd...), so the static figure is safe but not reached;
    // with a bound of 2 (one iteration) input 1 reaches it exactly.
    let b2 = Bounds::new().with_loop(head, 2);
    p.check("f", &b2, &[vec![0], vec![1]]);
    let b4 = Bounds::new().with_loop(head, 4);
    let w = p.wcet("f", &b4).unwrap();
    for n in 0..=3 {
        assert!(w.cycles >= p.run("f", &[n]));
    }
}

#[test]
fn nested_loops() {
    // for i in r0..0 { for j in 3..0 { r2 += 1 } }
    let mut p = Prog::new(&[
        l("f"),
        movs(2, 0),
        l("outer"),
        movs(1, 3),
        l("inner"),
        adds(2, 2, 1),
        subs(1, 1, 1),
        bc(NE, "inner"),
        subs(0, 0, 1),
        bc(NE, "outer"),
        I(Instr::MovHi { rd: 0, rm: 2 }),
        bx_lr(),
    ]);
    let bounds = Bounds::new()
        .with_loop(p.at("outer"), 4)
        .with_loop(p.at("inner"), 3);
    let inputs: Vec<Vec<u32>> = (1..=4).map(|k| vec![k]).collect();
    p.check("f", &bounds, &inputs);
    assert_eq!(p.run("f", &[4]), {
        // 1 + 4 × (1 + 3 × 2 + 2 × 2 + 1 + 1) + 3 × 2 + 1 + 1 + 2
        1 + 4 * (1 + 6 + 4 + 1 + 1) + 6 + 1 + 3
    });
    let e = p
        .wcet("f", &Bounds::new().with_loop(p.at("outer"), 4))
        .unwrap_err();
    assert_eq!(
        e,
        WcetError::UnboundedLoop {
            header: p.at("inner")
        }
    );
}

#[test]
fn loop_at_the_entry_with_a_break_a_return_inside_and_a_call() {
    // f: r0 -= 1; if r0 == r1 return early (POP {PC} inside the loop);
    //    if r0 == 7 break; bl g; while r0 != 0
    let mut p = Prog::new(&[
        l("f"),
        l("loop"),
        I(Instr::Push { list: 0x4000 }),
        subs(0, 0, 1),
        alu(AluOp::Cmp, 0, 1),
        bc(NE, "go"),
        I(Instr::Pop { list: 0x8000 }),
        l("go"),
        cmpi(0, 7),
        bc(EQ, "brk"),
        bl("g"),
        I(Instr::Pop { list: 0x04 }),
        I(Instr::MovHi { rd: 14, rm: 2 }),
        cmpi(0, 0),
        bc(NE, "loop"),
        bx_lr(),
        l("brk"),
        I(Instr::Pop { list: 0x04 }),
        I(Instr::MovHi { rd: 14, rm: 2 }),
        adds(0, 0, 5),
        bx_lr(),
        l("g"),
        nop(),
        nop(),
        bx_lr(),
    ]);
    assert_eq!(p.at("f"), p.at("loop"));
    let bounds = Bounds::new().with_loop(p.at("loop"), 6);
    let inputs: Vec<Vec<u32>> = (1..=6)
        .flat_map(|n| [vec![n, 100], vec![n, 0], vec![n, 2]])
        .collect();
    p.check("f", &bounds, &inputs);
    let w = p.wcet("f", &bounds).unwrap();
    assert_eq!(w.path.iter().filter(|&&a| a == p.at("loop")).count(), 6);
}

#[test]
fn isr_matches_a_timer_interrupt_on_the_board() {
    // The timer test of tests/exceptions.rs, built with the encoder: an alarm interrupt
    // every 23 us whose handler re-arms it and counts. The ISR's static WCET is exception
    // entry + body + exception return, as measured from the alarm to the return.
    let items = vec![
        l("reset"),
        Lit(0, "timer".into()),
        movs(1, 1),
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 1,
            rn: 0,
            imm: 0x38,
        }), // INTE = alarm 0
        Lit(2, "iser".into()),
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 1,
            rn: 2,
            imm: 0,
        }), // NVIC_ISER: IRQ 0
        I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: 1,
            rn: 0,
            imm: 0x28,
        }), // TIMERAWL
        adds(1, 1, 23),
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 1,
            rn: 0,
            imm: 0x10,
        }), // ALARM0
        l("spin"),
        I(Instr::Hint(tactus_isa::decode::Hint::Wfi)),
        b("spin"),
        l("isr"),
        Lit(0, "timer".into()),
        movs(1, 1),
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 1,
            rn: 0,
            imm: 0x34,
        }), // clear INTR
        I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: 1,
            rn: 0,
            imm: 0x10,
        }),
        adds(1, 1, 23),
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 1,
            rn: 0,
            imm: 0x10,
        }), // next alarm
        Lit(2, "count".into()),
        I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: 3,
            rn: 2,
            imm: 0,
        }),
        adds(3, 3, 1),
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 3,
            rn: 2,
            imm: 0,
        }),
        bx_lr(),
        Align,
        l("timer"),
        Word(0x4005_4000),
        l("iser"),
        Word(0xe000_e100),
        l("count"),
        Word(BASE + 0x800),
    ];
    let (bytes, labels) = assemble(BASE, &items);
    let vtor = BASE + 0x1000;
    let mut vectors = [0u32; 48];
    vectors[0] = SP;
    vectors[1] = labels["reset"] | 1;
    vectors[16] = labels["isr"] | 1; // IRQ 0: TIMER_IRQ_0
    let vbytes: Vec<u8> = vectors.iter().flat_map(|w| w.to_le_bytes()).collect();
    let mut board = Board::new(Config::default());
    board.write_bytes(BASE, &bytes).unwrap();
    board.write_bytes(vtor, &vbytes).unwrap();
    board.boot_from_vectors(0, vtor).unwrap();
    let handle = board.profile_addr(labels["isr"]);
    board.run_for(133 * 100);
    let calls = board.calls(handle).to_vec();
    assert_eq!(calls.len(), 100 / 23);
    let image = Image {
        base: BASE,
        bytes: &bytes,
    };
    let w = analyse_isr(&image, labels["isr"], &Bounds::new()).unwrap();
    let body = 2 + 1 + 4 + 3 + 1 + 4 + 2 + 2 + 1 + 2 + 2;
    assert_eq!(w.cycles, (EXCEPTION_ENTRY + body + EXCEPTION_RETURN) as u64);
    for (k, call) in calls.iter().enumerate() {
        let fire = 23 * (k as u64 + 1) * 133;
        let measured = call.start - fire + call.cycles;
        assert_eq!(w.cycles, measured, "call {k}: {call:?}");
    }
}

#[test]
fn call_to_helper_and_pop_pc_return() {
    let mut p = Prog::new(&[
        l("f"),
        I(Instr::Push { list: 0x4010 }), // push {r4, lr}
        movs(4, 2),
        bl("helper"),
        adds(0, 0, 1),
        bl("helper"),
        I(Instr::Pop { list: 0x8010 }), // pop {r4, pc}
        l("helper"),
        cmpi(0, 10),
        bc(GT, "big"),
        alu(AluOp::Mul, 0, 0),
        adds(0, 0, 3),
        l("big"),
        bx_lr(),
    ]);
    let helper = p.check("helper", &Bounds::new(), &[vec![0], vec![20]]);
    assert_eq!(helper, 1 + 1 + 2 + 2);
    let c = p.check(
        "f",
        &Bounds::new(),
        &[vec![0], vec![10], vec![11], vec![50]],
    );
    assert_eq!(c, 3 + 1 + 2 * (3 + helper) + 1 + 4);
    let w = p.wcet("f", &Bounds::new()).unwrap();
    assert_eq!(w.calls.len(), 2);
    assert!(w
        .calls
        .iter()
        .all(|s| s.callee == p.at("helper") && s.cycles == helper));
    // A declared callee WCET is used instead of analysing it.
    let w = p
        .wcet("f", &Bounds::new().with_call(p.at("helper"), 100))
        .unwrap();
    assert_eq!(w.cycles, 3 + 1 + 2 * 103 + 1 + 4);
}

/// A `BL` used as a long branch to a label of the same function (LR already pushed; the
/// target returns with `POP {…, PC}` to the function's caller): declared in
/// `Bounds::branch_links`, it is a jump — static == the worst run. As a call, the tail
/// from the target to the return would be counted after the `BL` as well.
#[test]
fn a_branch_link_within_the_function_is_a_jump() {
    let mut p = Prog::new(&[
        l("f"),
        I(Instr::Push { list: 0x4010 }), // push {r4, lr}: 3
        cmpi(0, 0),                      // 1
        bc(EQ, "skip"),                  // 1 / 2
        l("far"),
        bl("tail"), // 3: a long branch, never returns here
        l("skip"),
        adds(1, 1, 1),
        adds(1, 1, 1),
        l("tail"),
        alu(AluOp::Mul, 1, 1),
        adds(1, 1, 2),
        I(Instr::Pop { list: 0x8010 }), // pop {r4, pc}: 3 + 4
    ]);
    let bounds = Bounds::new().with_branch_link(p.at("far"));
    // Both paths run: static == the slower (`check`), and the BL path costs the BL's
    // cycles, not a call's.
    let c = p.check("f", &bounds, &[vec![0], vec![1]]);
    assert_eq!(p.run("f", &[1]).max(p.run("f", &[0])), c);
    let w = p.wcet("f", &bounds).unwrap();
    assert!(w.calls.is_empty());
    // As a call, the tail is counted twice (and the POP's return treated as the callee's).
    let as_call = p.wcet("f", &Bounds::new()).unwrap();
    assert_eq!(as_call.calls.len(), 1);
    assert!(as_call.cycles > c);
}

/// Flow facts: two `if` bodies that never both run. Excluding each in turn
/// (`Bounds::unexecuted`) and taking the larger bound gives exactly the worst feasible run;
/// without the facts the bound is the infeasible path through both.
#[test]
fn unexecuted_blocks_split_the_analysis_into_scenarios() {
    let mut p = Prog::new(&[
        l("f"),
        cmpi(0, 0),
        bc(EQ, "skip1"),
        l("a"),
        adds(2, 2, 1),
        adds(2, 2, 1),
        adds(2, 2, 1),
        l("skip1"),
        cmpi(1, 0),
        bc(EQ, "skip2"),
        l("b"),
        adds(2, 2, 1),
        adds(2, 2, 1),
        adds(2, 2, 1),
        adds(2, 2, 1),
        l("skip2"),
        bx_lr(),
    ]);
    let feasible = [vec![1, 0], vec![0, 1], vec![0, 0]]
        .iter()
        .map(|a| p.run("f", a))
        .max()
        .unwrap();
    let both = p.run("f", &[1, 1]);
    assert!(both > feasible);
    assert_eq!(p.wcet("f", &Bounds::new()).unwrap().cycles, both);
    let no_a = p
        .wcet("f", &Bounds::new().with_unexecuted(p.at("a")))
        .unwrap();
    let no_b = p
        .wcet("f", &Bounds::new().with_unexecuted(p.at("b")))
        .unwrap();
    assert_eq!(no_a.cycles.max(no_b.cycles), feasible);
    assert!(!no_a.path.contains(&p.at("a")) && !no_b.path.contains(&p.at("b")));
    // Excluding both arms leaves the path through neither; excluding the entry, none.
    let neither = Bounds::new()
        .with_unexecuted(p.at("a"))
        .with_unexecuted(p.at("b"));
    assert_eq!(p.wcet("f", &neither).unwrap().cycles, p.run("f", &[0, 0]));
    assert_eq!(
        p.wcet("f", &Bounds::new().with_unexecuted(p.at("f"))),
        Err(WcetError::NoReturn { entry: p.at("f") })
    );
}

#[test]
fn recursion_is_an_error() {
    let p = Prog::new(&[
        l("f"),
        I(Instr::Push { list: 0x4000 }),
        bl("g"),
        I(Instr::Pop { list: 0x8000 }),
        l("g"),
        I(Instr::Push { list: 0x4000 }),
        bl("f"),
        I(Instr::Pop { list: 0x8000 }),
    ]);
    let e = p.wcet("f", &Bounds::new()).unwrap_err();
    assert_eq!(
        e,
        WcetError::Recursion {
            callee: p.at("f"),
            site: p.at("g") + 2
        }
    );
}

#[test]
fn unanalysable_code_is_an_error_with_its_address() {
    for bad in [
        Instr::Bx { rm: 1 },
        Instr::Blx { rm: 2 },
        Instr::MovHi { rd: 15, rm: 3 },
        Instr::AddHi { rdn: 15, rm: 0 },
    ] {
        let p = Prog::new(&[l("f"), cmpi(0, 1), bc(EQ, "x"), bx_lr(), l("x"), I(bad)]);
        match p.wcet("f", &Bounds::new()).unwrap_err() {
            WcetError::IndirectBranch { addr, .. } => assert_eq!(addr, p.at("x")),
            e => panic!("{bad}: {e}"),
        }
    }
    for bad in [
        Instr::Svc { imm: 1 },
        Instr::Bkpt { imm: 0 },
        Instr::Udf { imm: 0 },
        Instr::Hint(tactus_isa::decode::Hint::Wfi),
    ] {
        let p = Prog::new(&[l("f"), nop(), l("x"), I(bad), bx_lr()]);
        match p.wcet("f", &Bounds::new()).unwrap_err() {
            WcetError::Unanalysable { addr, .. } => assert_eq!(addr, p.at("x")),
            e => panic!("{bad}: {e}"),
        }
    }
    // Falling off the end of the image.
    let p = Prog::new(&[l("f"), nop(), nop()]);
    assert_eq!(
        p.wcet("f", &Bounds::new()).unwrap_err(),
        WcetError::OutOfImage {
            addr: p.at("f") + 4
        }
    );
    // `b .` is a loop; with a bound it never exits.
    let p = Prog::new(&[l("f"), l("spin"), b("spin")]);
    let spin = p.at("spin");
    assert_eq!(
        p.wcet("f", &Bounds::new()).unwrap_err(),
        WcetError::UnboundedLoop { header: spin }
    );
    assert_eq!(
        p.wcet("f", &Bounds::new().with_loop(spin, 3)).unwrap_err(),
        WcetError::NoExit { header: spin }
    );
}

#[test]
fn literal_pools_are_data_and_io_port_accesses_cost_one_cycle() {
    // CPUID is SIO + 0 (1-cycle I/O port); TIMERAWL is on APB (3-cycle load). The literal
    // pool after the return holds words that decode to garbage (UDF) and must not be read
    // as code.
    let mut p = Prog::new(&[
        l("f"),
        Lit(3, "sio".into()),
        I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: 0,
            rn: 3,
            imm: 0,
        }), // 1 (I/O port)
        Lit(2, "timer".into()),
        I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: 1,
            rn: 2,
            imm: 0x28,
        }), // 2 + APB wait
        bx_lr(),
        Align,
        l("sio"),
        Word(0xd000_0000),
        l("timer"),
        Word(0x4005_4000),
        Word(0xdede_dede),
    ]);
    let c = p.check("f", &Bounds::new(), &[vec![]]);
    assert_eq!(c, 2 + 1 + 2 + 3 + 2);
    // Declaring the regions explicitly gives the same figure; unknown addresses are priced
    // as memory (2 cycles) unless declared.
    let w = analyse(
        &|a: u32| {
            let off = a.checked_sub(BASE)? as usize;
            Some(u16::from_le_bytes([
                *p.bytes.get(off)?,
                *p.bytes.get(off + 1)?,
            ]))
        },
        p.at("f"),
        &Bounds {
            unknown_access: Region::IoPort,
            ..Bounds::new()
        },
    )
    .unwrap();
    assert_eq!(w.cycles, c);
}

#[test]
fn unknown_addresses_follow_the_declared_region() {
    // ldr r0, [r0]: the pointer comes from the caller.
    let mut p = Prog::new(&[
        l("f"),
        I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: 0,
            rn: 0,
            imm: 0,
        }),
        bx_lr(),
    ]);
    let sram = p.check("f", &Bounds::new(), &[vec![0x2001_0000]]);
    assert_eq!(sram, 4);
    let at = p.at("f");
    let apb = Bounds::new().with_access(at, Region::Apb);
    assert_eq!(p.check("f", &apb, &[vec![0x4005_4028]]), 5);
    let io = Bounds::new().with_access(at, Region::IoPort);
    assert_eq!(p.check("f", &io, &[vec![0xd000_0000]]), 3);
    let pessimistic = Bounds {
        unknown_access: Region::Apb,
        ..Bounds::new()
    };
    assert_eq!(p.wcet("f", &pessimistic).unwrap().cycles, 5);
}

// ---- randomized: acyclic programs of forward branches ----

/// xorshift64*: a deterministic PRNG for the randomized tests.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// A random straight-line instruction over r0-r2, r5, r6 (r3 holds the path selector, r4 is
/// scratch for the selector tests, r7 counts loop iterations; SP points at 16 free bytes).
fn random_op(rng: &mut Rng) -> It {
    let r = |rng: &mut Rng| [0u8, 1, 2, 5, 6][rng.below(5) as usize];
    let lo = |rng: &mut Rng| [0u8, 1, 2, 5, 6][rng.below(5) as usize];
    match rng.below(9) {
        0 => movs(lo(rng), rng.below(256) as u8),
        1 => adds(lo(rng), lo(rng), rng.below(8) as u8),
        2 => alu(
            [
                AluOp::Eor,
                AluOp::Orr,
                AluOp::And,
                AluOp::Mul,
                AluOp::Adc,
                AluOp::Ror,
            ][rng.below(6) as usize],
            lo(rng),
            lo(rng),
        ),
        3 => I(Instr::LslImm {
            rd: lo(rng),
            rm: lo(rng),
            imm: rng.below(32) as u8,
        }),
        4 => I(Instr::MemImm {
            op: MemOp::Str,
            rt: r(rng),
            rn: 13,
            imm: 4 * rng.below(4) as u16,
        }),
        5 => I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: r(rng),
            rn: 13,
            imm: 4 * rng.below(4) as u16,
        }),
        6 => I(Instr::Push { list: 0x0060 }),
        7 => I(Instr::Pop { list: 0x0060 }),
        _ => nop(),
    }
}

/// `count` random segments labelled `{prefix}0`.. and a final label `{prefix}{count}`; each
/// segment ends in a forward branch within the group (on a selector bit of r3 when
/// `selector`, numbered from `*bits`, else on a data comparison; sometimes unconditional or
/// none) and, when `with_call`, sometimes calls `helper`.
fn segments(
    rng: &mut Rng,
    prefix: &str,
    count: usize,
    selector: bool,
    with_call: bool,
    bits: &mut u32,
) -> Vec<It> {
    let mut items = Vec::new();
    for s in 0..count {
        items.push(l(&format!("{prefix}{s}")));
        // Keep PUSH/POP balanced inside a segment.
        let mut depth = 0;
        for _ in 0..rng.below(5) {
            let op = random_op(rng);
            match op {
                I(Instr::Push { .. }) => depth += 1,
                I(Instr::Pop { .. }) if depth == 0 => continue,
                I(Instr::Pop { .. }) => depth -= 1,
                _ => {}
            }
            items.push(op);
        }
        for _ in 0..depth {
            items.push(I(Instr::Pop { list: 0x0060 }));
        }
        if with_call && rng.below(4) == 0 {
            items.push(bl("helper"));
        }
        // Targets within 8 segments stay in B<cond> range (±256 bytes).
        let reach = (count - s).min(8) as u64;
        let target = format!("{prefix}{}", s + 1 + rng.below(reach) as usize);
        match rng.below(6) {
            0 => items.push(b(&target)),
            1 => {} // fall through
            _ if selector && *bits < 31 => {
                items.push(I(Instr::MovHi { rd: 4, rm: 3 }));
                items.push(I(Instr::LsrImm {
                    rd: 4,
                    rm: 4,
                    imm: (*bits + 1) as u8,
                }));
                *bits += 1;
                items.push(bc(if rng.below(2) == 0 { CS } else { CC }, &target));
            }
            _ => {
                items.push(alu(AluOp::Cmp, 0, 1));
                items.push(bc([EQ, NE, GT, LE, CS, CC][rng.below(6) as usize], &target));
            }
        }
    }
    items.push(l(&format!("{prefix}{count}")));
    items
}

/// A helper with a data-dependent branch (called with whatever r0 holds).
fn helper() -> Vec<It> {
    vec![
        l("helper"),
        cmpi(0, 100),
        bc(CC, "hdone"),
        alu(AluOp::Mul, 0, 0),
        adds(0, 0, 1),
        l("hdone"),
        bx_lr(),
    ]
}

/// A random function: prologue, `count` segments (see [`segments`]), optionally inside a
/// loop counted by r7 that runs `loop_n` times, epilogue. Returns the items and the number
/// of selector bits used.
fn random_program(
    rng: &mut Rng,
    count: usize,
    selector: bool,
    with_call: bool,
    loop_n: Option<u8>,
) -> (Vec<It>, u32) {
    let mut items = vec![
        l("f"),
        I(Instr::Push { list: 0x40f0 }),
        I(Instr::SubSp { imm: 16 }),
    ];
    if let Some(n) = loop_n {
        // r7 counts the iterations (the random code never writes it).
        items.push(movs(7, n));
        items.push(l("loop"));
    }
    let mut bits = 0u32;
    items.extend(segments(rng, "s", count, selector, with_call, &mut bits));
    if loop_n.is_some() {
        items.push(subs(7, 7, 1));
        items.push(bc(NE, "loop"));
    }
    items.push(I(Instr::AddSp { imm: 16 }));
    items.push(I(Instr::Pop { list: 0x80f0 }));
    items.extend(helper());
    (items, bits)
}

/// Two nested counted loops around random segments: outer (r7) runs `no` times, inner (its
/// counter at [sp, #16], out of reach of the random stores) `ni` times.
fn random_nested(rng: &mut Rng, no: u8, ni: u8, with_call: bool) -> (Vec<It>, u32) {
    let mut bits = 0;
    let mut items = vec![
        l("f"),
        I(Instr::Push { list: 0x40f0 }),
        I(Instr::SubSp { imm: 20 }),
        movs(7, no),
        l("outer"),
    ];
    let n = 1 + rng.below(3) as usize;
    items.extend(segments(rng, "a", n, true, with_call, &mut bits));
    items.extend([
        movs(4, ni),
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 4,
            rn: 13,
            imm: 16,
        }),
        l("inner"),
    ]);
    let n = 1 + rng.below(3) as usize;
    items.extend(segments(rng, "b", n, true, with_call, &mut bits));
    items.extend([
        I(Instr::MemImm {
            op: MemOp::Ldr,
            rt: 4,
            rn: 13,
            imm: 16,
        }),
        subs(4, 4, 1),
        I(Instr::MemImm {
            op: MemOp::Str,
            rt: 4,
            rn: 13,
            imm: 16,
        }),
        bc(NE, "inner"),
    ]);
    let n = 1 + rng.below(3) as usize;
    items.extend(segments(rng, "c", n, true, with_call, &mut bits));
    items.extend([
        subs(7, 7, 1),
        bc(NE, "outer"),
        I(Instr::AddSp { imm: 20 }),
        I(Instr::Pop { list: 0x80f0 }),
    ]);
    items.extend(helper());
    (items, bits)
}

#[test]
fn random_programs_static_equals_the_worst_run() {
    let mut rng = Rng(0x007a_c705_2026);
    let (mut exact, mut paths) = (0, 0);
    for round in 0..60 {
        let segments = 1 + rng.below(7) as usize;
        let with_call = round % 3 == 0;
        // Every other program runs its segments in a counted loop: the selector bits are
        // the same in every iteration, so the worst iteration repeats and the bound is exact.
        let loop_n = (round % 2 == 1).then(|| 1 + rng.below(5) as u8);
        let (items, bits) = random_program(&mut rng, segments, true, with_call, loop_n);
        let mut p = Prog::new(&items);
        let bounds = match loop_n {
            Some(n) => Bounds::new().with_loop(p.at("loop"), n as u32),
            None => Bounds::new(),
        };
        let w = p.wcet("f", &bounds).unwrap();
        let mut worst = 0;
        paths += 1u32 << bits;
        for sel in 0..(1u32 << bits) {
            // r0 = 200 makes the helper take its long arm whenever r0 is untouched.
            let args = [200, rng.next() as u32, rng.next() as u32, sel];
            let m = p.run("f", &args);
            assert!(
                w.cycles >= m,
                "round {round}: static {} < {m}\n{items:?}",
                w.cycles
            );
            worst = worst.max(m);
        }
        if !with_call {
            assert_eq!(w.cycles, worst, "round {round}: {items:?}");
            exact += 1;
        }
    }
    assert!(exact >= 30);
    eprintln!("{exact} programs exact, {paths} selector runs");
    assert!(paths >= 200);
}

#[test]
fn random_data_dependent_programs_are_never_under_estimated() {
    let mut rng = Rng(0x5eed_1234_abcd);
    for round in 0..40 {
        let segments = 2 + rng.below(10) as usize;
        let loop_n = (round % 3 == 0).then(|| 1 + rng.below(4) as u8);
        let (items, _) = random_program(&mut rng, segments, false, round % 2 == 0, loop_n);
        let mut p = Prog::new(&items);
        let bounds = match loop_n {
            Some(n) => Bounds::new().with_loop(p.at("loop"), n as u32),
            None => Bounds::new(),
        };
        let w = p.wcet("f", &bounds).unwrap();
        for _ in 0..20 {
            let v = |rng: &mut Rng| match rng.below(3) {
                0 => rng.below(4) as u32,
                1 => rng.next() as u32,
                _ => 200,
            };
            let args = [v(&mut rng), v(&mut rng), v(&mut rng), v(&mut rng)];
            let m = p.run("f", &args);
            assert!(
                w.cycles >= m,
                "round {round}: static {} < {m}\n{items:?}",
                w.cycles
            );
        }
    }
}

#[test]
fn random_nested_loops_static_equals_the_worst_run() {
    let mut rng = Rng(0x0bad_cafe_f00d);
    for round in 0..30 {
        let (no, ni) = (1 + rng.below(4) as u8, 1 + rng.below(4) as u8);
        let with_call = round % 4 == 0;
        let (items, bits) = random_nested(&mut rng, no, ni, with_call);
        let mut p = Prog::new(&items);
        let bounds = Bounds::new()
            .with_loop(p.at("outer"), no as u32)
            .with_loop(p.at("inner"), ni as u32);
        let w = p.wcet("f", &bounds).unwrap();
        let mut worst = 0;
        for sel in 0..(1u32 << bits.min(8)) {
            let m = p.run("f", &[200, rng.next() as u32, rng.next() as u32, sel]);
            assert!(
                w.cycles >= m,
                "round {round}: static {} < {m}\n{items:?}",
                w.cycles
            );
            worst = worst.max(m);
        }
        if !with_call && bits <= 8 {
            assert_eq!(w.cycles, worst, "round {round}: {items:?}");
        }
        // The worst path passes the inner header no × ni times.
        let inner = w.path.iter().filter(|&&a| a == p.at("inner")).count();
        assert_eq!(inner, no as usize * ni as usize);
    }
}

#[test]
fn large_programs_are_analysed_quickly() {
    let mut rng = Rng(0x1a26e);
    let (items, _) = random_program(&mut rng, 400, false, true, None);
    let mut p = Prog::new(&items);
    let bounds = Bounds::new();
    let t = std::time::Instant::now();
    let w = p.wcet("f", &bounds).unwrap();
    let elapsed = t.elapsed();
    eprintln!(
        "{} blocks, WCET {} cycles, analysed in {elapsed:?}",
        w.blocks.len(),
        w.cycles
    );
    assert!(w.blocks.len() > 300);
    for k in 0..10u32 {
        let m = p.run("f", &[k, 200, k * 7, 3]);
        assert!(w.cycles >= m);
    }
}

#[test]
fn a_branch_into_the_middle_of_a_32_bit_instruction_is_an_error() {
    // 0: cmp r0, #0; 2: beq 6; 4: bl (second halfword 0xd001 = `beq` when read at 6);
    // 8, 10, 12: bx lr. The code is given as a closure over halfwords.
    let hw = [0x2800u16, 0xd000, 0xf400, 0xd001, 0x4770, 0x4770, 0x4770];
    let code = |a: u32| hw.get(a.checked_sub(BASE)? as usize / 2).copied();
    assert_eq!(
        analyse(&code, BASE, &Bounds::new()).unwrap_err(),
        WcetError::Overlap { addr: BASE + 6 }
    );
}

#[test]
fn a_path_placed_below_the_entry() {
    // The entry branches back to a path at a lower address (no loop: it returns), as a
    // handler's rare path placed before it. The analysis starts at the entry, not at the
    // lowest block: a root taken from the lowest address priced the rare path alone.
    let mut p = Prog::new(&[
        l("rare"),
        movs(1, 1), // 1
        bx_lr(),    // 2
        l("f"),
        cmpi(0, 0),     // 1
        bc(EQ, "rare"), // 2 taken, 1 not
        adds(1, 1, 1),  // 1
        adds(1, 1, 1),  // 1
        adds(1, 1, 1),  // 1
        adds(1, 1, 1),  // 1
        adds(1, 1, 1),  // 1
        bx_lr(),        // 2
    ]);
    let c = p.check("f", &Bounds::new(), &[vec![0], vec![1], vec![9]]);
    assert_eq!(c, 1 + 1 + 5 + 2);
    let w = p.wcet("f", &Bounds::new()).unwrap();
    assert_eq!(w.path, vec![p.at("f"), w.blocks[2].start]);
    // The rare path: 1 + 2 + 1 + 2 = 6, under the common one.
    assert_eq!(p.run("f", &[0]), 6);
}
