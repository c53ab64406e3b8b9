//! Static worst-case execution time (WCET) of Thumb machine code, in core clock cycles.
//!
//! [`analyse`] decodes the instructions reachable from a function's entry (literal pools and
//! other data are never decoded unless control reaches them), splits them into basic blocks,
//! builds the control-flow graph and returns the longest path from the entry to a return,
//! priced with [`timing::cycles`] — the table the executor charges, which encodes the
//! Cortex-M0+ Technical Reference Manual (ARM DDI 0484C) §3.3, table 3-1. A conditional
//! branch costs its *taken* cycles on the taken edge and its *not-taken* cycles on the
//! fall-through edge. [`analyse_isr`] adds exception entry and return
//! ([`EXCEPTION_ENTRY`], [`EXCEPTION_RETURN`]).
//!
//! **Control flow.** `B`, `B<cond>` (two edges), `BL` (the callee is analysed as a function
//! with the same [`Bounds`] and its WCET added at the call site, after the `BL`'s own 3
//! cycles; recursion is an error; a `BL` listed in [`Bounds::branch_links`] is a long
//! branch within the function instead) and returns: `BX LR`, `MOV PC, LR` and `POP {…, PC}` (each
//! assumed to return to the caller: LR, or the LR pushed on entry, intact — as AAPCS code
//! guarantees). Anything whose target is not
//! known statically — `BX` of another register, `BLX`, `MOV`/`ADD` to PC — and anything that
//! does not continue in bounded time (`SVC`, `BKPT`, `UDF`, undefined encodings, `WFI`,
//! `WFE`) is a [`WcetError`] naming its address; the analysis never panics and never
//! silently under-estimates the control flow.
//!
//! **Loops** are the natural loops of the back edges found with dominators (an irreducible
//! graph is an error). Each needs a bound in [`Bounds::loops`], keyed by the address of its
//! header (the first instruction of the loop's entry block): the maximum number of times the
//! header block executes per entry into the loop, i.e. back edges taken + 1. A loop is
//! collapsed, innermost first, into a node costing `(bound − 1) × (longest iteration) +
//! (longest path from the header to the exit)` for each of its exits (the classic
//! implicit-path bound: exact when the longest iteration can repeat, otherwise safe).
//!
//! **Memory costs assumed.** Code is fetched without wait states (as the emulator assumes).
//! Single loads and stores cost the table's bus figure (2 cycles) unless their address is
//! known to lie in the single-cycle I/O port (SIO, 0xd0000000–0xdfffffff: 1 cycle, the
//! table's `io_port` figure) or on APB (0x40000000–0x4fffffff: plus
//! [`APB_LOAD_WAIT`]/[`APB_STORE_WAIT`]). An address is known when a [`Bounds::accesses`]
//! entry names the instruction's region, or else when a small constant propagation inside
//! the basic block finds the base (and index) register values (`MOVS #imm`, `LDR` from a
//! literal in the image, `ADR`, `ADDS`/`SUBS #imm`, `LSLS`/`LSRS #imm`, `ADDS Rd, Rn, Rm`,
//! `MOV`); literal loads (`LDR Rt, [PC, #imm]`) always know their address. An access whose
//! address is not known is priced as [`Bounds::unknown_access`], by default
//! [`Region::Memory`] — the more expensive of the bus and the I/O port, but *not* APB: code
//! that reaches APB through a pointer the analysis cannot see must say so in
//! [`Bounds::accesses`] (or set `unknown_access` to [`Region::Apb`]). `LDM`/`STM` are priced
//! as memory unless their base is known (or `unknown_access` says) to be APB; `PUSH`, `POP`
//! and SP-relative loads and stores as memory (the stack is in SRAM). SRAM
//! accesses are assumed to meet no bank contention from the other core (the emulator's
//! one-cycle arbitration wait is not included), and flash as zero-wait (as the emulator
//! models it). The hardware divider does not stall a read, so it costs nothing extra here.

use crate::decode::{self, Instr};
use crate::effects;
use crate::timing::{self, APB_LOAD_WAIT, APB_STORE_WAIT, EXCEPTION_ENTRY, EXCEPTION_RETURN};
use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::fmt;

/// Where the analysed code comes from: halfwords (and words, for literal pools) by address.
pub trait Code {
    /// The halfword at the even address `addr`, or `None` outside the image.
    fn halfword(&self, addr: u32) -> Option<u16>;
    /// The little-endian word at `addr` (two halfwords), or `None` outside the image.
    fn word(&self, addr: u32) -> Option<u32> {
        let lo = self.halfword(addr)?;
        let hi = self.halfword(addr.wrapping_add(2))?;
        Some(lo as u32 | (hi as u32) << 16)
    }
}

impl<F: Fn(u32) -> Option<u16>> Code for F {
    fn halfword(&self, addr: u32) -> Option<u16> {
        self(addr)
    }
}

/// A code image: `bytes` loaded at address `base` (little-endian, as in memory).
#[derive(Clone, Copy, Debug)]
pub struct Image<'a> {
    /// Address of `bytes[0]`.
    pub base: u32,
    /// The image's bytes.
    pub bytes: &'a [u8],
}

impl Code for Image<'_> {
    fn halfword(&self, addr: u32) -> Option<u16> {
        let off = addr.checked_sub(self.base)? as usize;
        let b = self.bytes.get(off..off.checked_add(2)?)?;
        Some(u16::from_le_bytes([b[0], b[1]]))
    }
}

/// Which kind of memory a data access reaches, for its cost (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Region {
    /// SRAM, flash, ROM or the private peripheral bus: the table's bus cost, no wait states.
    #[default]
    Memory,
    /// The single-cycle I/O port (SIO, 0xd0000000): the table's `io_port` cost (1 cycle).
    IoPort,
    /// An APB peripheral (0x40000000): the bus cost plus [`APB_LOAD_WAIT`] or
    /// [`APB_STORE_WAIT`] per transferred word.
    Apb,
}

impl Region {
    /// The region an address lies in, as the emulator's bus decides it.
    pub fn of(addr: u32) -> Region {
        match addr >> 28 {
            0xd => Region::IoPort,
            0x4 => Region::Apb,
            _ => Region::Memory,
        }
    }
}

/// What the analysis cannot find out by itself: loop bounds, externally known callees and
/// the memory regions of accesses through pointers.
#[derive(Clone, Debug, Default)]
pub struct Bounds {
    /// Loop header address (Thumb bit clear) → maximum number of times the header block
    /// executes per entry into the loop (back edges taken + 1; at least 1).
    pub loops: HashMap<u32, u32>,
    /// Callee address → its WCET in cycles (first instruction to return, inclusive), used
    /// instead of analysing a `BL` target (e.g. a routine outside the image).
    pub calls: HashMap<u32, u64>,
    /// Address of a load/store instruction → the region its data access reaches (overrides
    /// the constant propagation).
    pub accesses: HashMap<u32, Region>,
    /// Region assumed for an access whose address is not known (default [`Region::Memory`]).
    pub unknown_access: Region,
    /// Addresses of `BL` instructions that are long *branches*, not calls: code generators
    /// use `BL` (±4 MiB) to reach a label in the same function beyond `B`'s ±2 KiB, with LR
    /// already saved. Such a `BL` is analysed as `B` to its target (costing the `BL`'s
    /// cycles); as a call, the rest of the function would be counted twice.
    pub branch_links: HashSet<u32>,
    /// Start addresses of blocks the analysed call does not execute (flow facts supplied
    /// by the caller): no path through them is counted. Used to split the analysis into
    /// scenarios — for two blocks that never both run, the maximum over "the first does
    /// not run" and "the second does not run" is a bound that excludes the infeasible path
    /// through both. An address that is not a block start has no effect.
    pub unexecuted: HashSet<u32>,
}

impl Bounds {
    /// No bounds: only loop-free code can be analysed.
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds a loop bound: the header at `header` executes at most `max` times per entry.
    pub fn with_loop(mut self, header: u32, max: u32) -> Self {
        self.loops.insert(header & !1, max);
        self
    }
    /// Declares the WCET (cycles, first instruction to return inclusive) of the callee at
    /// `addr`.
    pub fn with_call(mut self, addr: u32, cycles: u64) -> Self {
        self.calls.insert(addr & !1, cycles);
        self
    }
    /// Declares the region the load/store at `addr` accesses.
    pub fn with_access(mut self, addr: u32, region: Region) -> Self {
        self.accesses.insert(addr & !1, region);
        self
    }
    /// Declares that the block starting at `addr` is not executed (see
    /// [`Bounds::unexecuted`]).
    pub fn with_unexecuted(mut self, addr: u32) -> Self {
        self.unexecuted.insert(addr & !1);
        self
    }
    /// Declares the `BL` at `addr` a long branch within its function (see
    /// [`Bounds::branch_links`]).
    pub fn with_branch_link(mut self, addr: u32) -> Self {
        self.branch_links.insert(addr & !1);
        self
    }
}

/// Why code could not be analysed. Every variant names an address.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum WcetError {
    /// A loop whose header (at `header`) has no entry in [`Bounds::loops`].
    UnboundedLoop {
        /// Address of the loop header.
        header: u32,
    },
    /// A loop bound of 0 (a header reached at all executes at least once).
    ZeroBound {
        /// Address of the loop header.
        header: u32,
    },
    /// A bounded loop with no path out of it (and no return inside it).
    NoExit {
        /// Address of the loop header.
        header: u32,
    },
    /// A function with no path to a return.
    NoReturn {
        /// The function's entry.
        entry: u32,
    },
    /// A branch whose target is not known statically (`BX Rm` other than LR, `BLX Rm`,
    /// `MOV PC, Rm` other than LR, `ADD PC, Rm`).
    IndirectBranch {
        /// Address of the branch.
        addr: u32,
        /// The instruction, printed.
        instr: String,
    },
    /// An instruction that does not continue in bounded time (SVC, BKPT, UDF, undefined
    /// encodings, WFI, WFE).
    Unanalysable {
        /// Address of the instruction.
        addr: u32,
        /// The instruction, printed.
        instr: String,
    },
    /// Two reachable instructions overlap (a branch into the middle of a 32-bit one).
    Overlap {
        /// Address of the second instruction.
        addr: u32,
    },
    /// Control reaches an address outside the code image.
    OutOfImage {
        /// The address.
        addr: u32,
    },
    /// A function calls itself, directly or not.
    Recursion {
        /// The function called again while being analysed.
        callee: u32,
        /// The `BL` that calls it.
        site: u32,
    },
    /// A control-flow graph with a cycle that is not a natural loop (entered other than
    /// through its header).
    Irreducible {
        /// A block on the cycle.
        addr: u32,
    },
}

impl fmt::Display for WcetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WcetError::UnboundedLoop { header } => {
                write!(
                    f,
                    "the loop with header {header:#010x} has no iteration bound"
                )
            }
            WcetError::ZeroBound { header } => {
                write!(f, "the loop with header {header:#010x} has a bound of 0")
            }
            WcetError::NoExit { header } => {
                write!(f, "the loop with header {header:#010x} never exits")
            }
            WcetError::NoReturn { entry } => {
                write!(f, "the function at {entry:#010x} never returns")
            }
            WcetError::IndirectBranch { addr, instr } => {
                write!(f, "indirect branch `{instr}` at {addr:#010x}")
            }
            WcetError::Unanalysable { addr, instr } => {
                write!(f, "`{instr}` at {addr:#010x} has no bounded execution time")
            }
            WcetError::Overlap { addr } => {
                write!(
                    f,
                    "the instruction at {addr:#010x} overlaps the one before it"
                )
            }
            WcetError::OutOfImage { addr } => {
                write!(f, "control reaches {addr:#010x}, outside the code image")
            }
            WcetError::Recursion { callee, site } => {
                write!(f, "recursive call of {callee:#010x} at {site:#010x}")
            }
            WcetError::Irreducible { addr } => {
                write!(f, "irreducible control flow at {addr:#010x}")
            }
        }
    }
}

impl std::error::Error for WcetError {}

/// One basic block's cost.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockCost {
    /// Address of its first instruction.
    pub start: u32,
    /// Address just past its last instruction.
    pub end: u32,
    /// Cycles of the block on its most expensive outcome (its terminator's taken or
    /// not-taken cost, whichever is larger), callees' WCET included.
    pub cycles: u64,
}

/// One `BL` in an analysed function.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CallSite {
    /// Address of the `BL`.
    pub site: u32,
    /// Address of the callee.
    pub callee: u32,
    /// The callee's WCET (cycles, first instruction to return inclusive; the `BL`'s own 3
    /// cycles not included).
    pub cycles: u64,
}

/// The result of an analysis.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Wcet {
    /// Worst-case cycles: from the function's first instruction to its return, inclusive
    /// (for [`analyse_isr`]: from the exception being taken to the handler's return
    /// completing).
    pub cycles: u64,
    /// Start addresses of the blocks on a worst path, in execution order (a loop's blocks
    /// repeated once per iteration; callees' blocks not listed).
    pub path: Vec<u32>,
    /// Every reachable block of the function, by address.
    pub blocks: Vec<BlockCost>,
    /// Every call site of the function, by address.
    pub calls: Vec<CallSite>,
}

/// The WCET of the function at `entry` (Thumb bit ignored) in `code`, in cycles from its
/// first instruction to its return inclusive — the figure the emulator's `Board::call` measures.
pub fn analyse(code: &dyn Code, entry: u32, bounds: &Bounds) -> Result<Wcet, WcetError> {
    let mut cx = Cx {
        code,
        bounds,
        stack: Vec::new(),
        done: HashMap::new(),
    };
    cx.function(entry & !1)
}

/// The WCET of an exception handler at `entry`: [`EXCEPTION_ENTRY`] + the handler's body
/// ([`analyse`]) + [`EXCEPTION_RETURN`], in cycles from the exception being taken to the
/// return completing (no tail-chaining, no preemption by other exceptions).
pub fn analyse_isr(code: &dyn Code, entry: u32, bounds: &Bounds) -> Result<Wcet, WcetError> {
    let mut w = analyse(code, entry, bounds)?;
    w.cycles += (EXCEPTION_ENTRY + EXCEPTION_RETURN) as u64;
    Ok(w)
}

struct Cx<'a> {
    code: &'a dyn Code,
    bounds: &'a Bounds,
    /// Functions being analysed (for recursion).
    stack: Vec<u32>,
    /// Callee WCETs already computed.
    done: HashMap<u32, u64>,
}

/// How an instruction leaves its block.
enum Flow {
    /// Continues with the next instruction.
    Next,
    /// `B`: to the target.
    Jump(u32),
    /// `B<cond>`: target when taken, the next instruction otherwise.
    Cond(u32),
    /// A return.
    Return,
    /// `BL` to the target, then the next instruction.
    Call(u32),
}

fn flow(addr: u32, instr: &Instr) -> Result<Flow, WcetError> {
    use Instr::*;
    let rel = |offset: i32| addr.wrapping_add(4).wrapping_add(offset as u32);
    Ok(match *instr {
        B { offset } => Flow::Jump(rel(offset)),
        BCond { offset, .. } => Flow::Cond(rel(offset)),
        Bl { offset } => Flow::Call(rel(offset)),
        Bx { rm: 14 } | MovHi { rd: 15, rm: 14 } => Flow::Return,
        Pop { list } if list & 0x8000 != 0 => Flow::Return,
        Bx { .. } | Blx { .. } | MovHi { rd: 15, .. } | AddHi { rdn: 15, .. } => {
            return Err(WcetError::IndirectBranch {
                addr,
                instr: instr.to_string(),
            })
        }
        Svc { .. }
        | Bkpt { .. }
        | Udf { .. }
        | Undefined { .. }
        | Hint(decode::Hint::Wfi | decode::Hint::Wfe) => {
            return Err(WcetError::Unanalysable {
                addr,
                instr: instr.to_string(),
            })
        }
        _ => Flow::Next,
    })
}

/// A decoded instruction.
#[derive(Clone, Copy)]
struct Ins {
    instr: Instr,
    size: u32,
}

/// A block's successor: `None` is a return.
#[derive(Clone, Copy, Debug)]
struct Edge {
    to: Option<usize>,
    cost: u64,
}

struct Block {
    start: u32,
    end: u32,
    body: u64,
    edges: Vec<Edge>,
}

/// A node of a region's acyclic graph: a block or a collapsed inner loop.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
enum Node {
    Block(usize),
    Loop(usize),
}

/// Where a region edge ends.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, PartialOrd, Ord)]
enum Sink {
    /// A back edge to the region's header.
    Back,
    /// Leaves the region to the block (or returns: `None`).
    Exit(Option<usize>),
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Target {
    Node(Node),
    Sink(Sink),
}

struct Loop {
    header: usize,
    body: Vec<bool>,
    size: usize,
    bound: u32,
    /// Collapsed form: per exit target (None = return), cycles from entering the header to
    /// taking the exit edge, and the block path.
    exits: Vec<(Option<usize>, u64, Vec<u32>)>,
}

impl Cx<'_> {
    fn fetch(&self, addr: u32) -> Result<Ins, WcetError> {
        let hw1 = self
            .code
            .halfword(addr)
            .ok_or(WcetError::OutOfImage { addr })?;
        let size = decode::size_of(hw1);
        let hw2 = if size == 4 {
            self.code
                .halfword(addr.wrapping_add(2))
                .ok_or(WcetError::OutOfImage { addr })?
        } else {
            0
        };
        Ok(Ins {
            instr: decode::decode(hw1, hw2),
            size,
        })
    }

    /// [`flow`], with the `BL`s declared in [`Bounds::branch_links`] as jumps.
    fn flow(&self, addr: u32, instr: &Instr) -> Result<Flow, WcetError> {
        Ok(match flow(addr, instr)? {
            Flow::Call(t) if self.bounds.branch_links.contains(&addr) => Flow::Jump(t),
            f => f,
        })
    }

    fn callee(&mut self, site: u32, target: u32) -> Result<u64, WcetError> {
        if let Some(&c) = self.bounds.calls.get(&target) {
            return Ok(c);
        }
        if let Some(&c) = self.done.get(&target) {
            return Ok(c);
        }
        if self.stack.contains(&target) {
            return Err(WcetError::Recursion {
                callee: target,
                site,
            });
        }
        let w = self.function(target)?;
        self.done.insert(target, w.cycles);
        Ok(w.cycles)
    }

    fn function(&mut self, entry: u32) -> Result<Wcet, WcetError> {
        self.stack.push(entry);
        let r = self.function_inner(entry);
        self.stack.pop();
        r
    }

    fn function_inner(&mut self, entry: u32) -> Result<Wcet, WcetError> {
        // 1. Reachable instructions and block leaders.
        let mut instrs: BTreeMap<u32, Ins> = BTreeMap::new();
        let mut leaders: BTreeSet<u32> = BTreeSet::new();
        leaders.insert(entry);
        let mut work = vec![entry];
        while let Some(addr) = work.pop() {
            if instrs.contains_key(&addr) {
                continue;
            }
            let ins = self.fetch(addr)?;
            instrs.insert(addr, ins);
            let next = addr.wrapping_add(ins.size);
            match self.flow(addr, &ins.instr)? {
                Flow::Next | Flow::Call(_) => work.push(next),
                Flow::Jump(t) => {
                    leaders.insert(t);
                    work.push(t);
                }
                Flow::Cond(t) => {
                    leaders.insert(t);
                    leaders.insert(next);
                    work.push(next);
                    work.push(t);
                }
                Flow::Return => {}
            }
        }
        // An instruction overlapping another (a branch into the middle of a 32-bit one) is
        // not a program the analysis can trust.
        let mut prev_end = 0u32;
        for (&a, ins) in &instrs {
            if a < prev_end {
                return Err(WcetError::Overlap { addr: a });
            }
            prev_end = a + ins.size;
        }

        // 2. Blocks, with their costs.
        let index: HashMap<u32, usize> = leaders.iter().enumerate().map(|(i, &a)| (a, i)).collect();
        let mut blocks = Vec::with_capacity(leaders.len());
        let mut calls = Vec::new();
        for &start in &leaders {
            let mut addr = start;
            let mut body = 0u64;
            let mut consts = Consts::new();
            let edges;
            loop {
                let ins = instrs[&addr];
                let next = addr.wrapping_add(ins.size);
                let f = self.flow(addr, &ins.instr)?;
                let plain = timing::cycles(&ins.instr, false, false) as u64;
                match f {
                    Flow::Jump(t) => {
                        edges = vec![Edge {
                            to: Some(index[&t]),
                            cost: plain,
                        }];
                    }
                    Flow::Cond(t) => {
                        edges = vec![
                            Edge {
                                to: Some(index[&t]),
                                cost: timing::cycles(&ins.instr, true, false) as u64,
                            },
                            Edge {
                                to: Some(index[&next]),
                                cost: plain,
                            },
                        ];
                    }
                    Flow::Return => {
                        edges = vec![Edge {
                            to: None,
                            cost: plain,
                        }]
                    }
                    Flow::Call(_) | Flow::Next => {
                        if let Flow::Call(t) = f {
                            let c = self.callee(addr, t)?;
                            calls.push(CallSite {
                                site: addr,
                                callee: t,
                                cycles: c,
                            });
                            body = body.saturating_add(plain.saturating_add(c));
                            consts = Consts::new();
                        } else {
                            body += self.cost(addr, &ins.instr, &consts);
                            consts.step(self.code, addr, &ins.instr);
                        }
                        addr = next;
                        if let Some(&i) = index.get(&next) {
                            edges = vec![Edge {
                                to: Some(i),
                                cost: 0,
                            }];
                            blocks.push(Block {
                                start,
                                end: next,
                                body,
                                edges,
                            });
                            break;
                        }
                        continue;
                    }
                }
                blocks.push(Block {
                    start,
                    end: next,
                    body,
                    edges,
                });
                break;
            }
        }

        // 3. Dominators, back edges, natural loops. The entry's block is the root, wherever
        // it lies: blocks are numbered by address, and code the function reaches may lie
        // below its entry (a path placed before it).
        let n = blocks.len();
        let root = index[&entry];
        let order = dfs_order(&blocks, root);
        let mut rpo_num = vec![usize::MAX; n];
        for (i, &b) in order.iter().enumerate() {
            rpo_num[b] = i;
        }
        let mut preds: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (b, blk) in blocks.iter().enumerate() {
            for e in &blk.edges {
                if let Some(t) = e.to {
                    if !preds[t].contains(&b) {
                        preds[t].push(b);
                    }
                }
            }
        }
        let idom = dominators(&order, &rpo_num, &preds, root);
        let dominates = |a: usize, mut b: usize| loop {
            if a == b {
                return true;
            }
            if b == root {
                return false;
            }
            b = idom[b];
        };
        let mut loops: Vec<Loop> = Vec::new();
        let mut loop_of_header: HashMap<usize, usize> = HashMap::new();
        for &b in &order {
            for e in &blocks[b].edges {
                let Some(h) = e.to else { continue };
                if rpo_num[h] > rpo_num[b] {
                    continue; // forward edge
                }
                // A retreating edge (target no later in reverse postorder): must be a back
                // edge, whose target dominates its source.
                if !dominates(h, b) {
                    return Err(WcetError::Irreducible {
                        addr: blocks[h].start,
                    });
                }
                let li = *loop_of_header.entry(h).or_insert_with(|| {
                    loops.push(Loop {
                        header: h,
                        body: vec![false; n],
                        size: 0,
                        bound: 0,
                        exits: Vec::new(),
                    });
                    loops.len() - 1
                });
                // Natural loop: h plus everything reaching b without passing h.
                let l = &mut loops[li];
                l.body[h] = true;
                let mut stack = vec![b];
                while let Some(x) = stack.pop() {
                    if l.body[x] {
                        continue;
                    }
                    l.body[x] = true;
                    stack.extend(preds[x].iter().copied());
                }
            }
        }
        for l in &mut loops {
            l.size = l.body.iter().filter(|&&x| x).count();
            let header = blocks[l.header].start;
            l.bound = match self.bounds.loops.get(&header) {
                None => return Err(WcetError::UnboundedLoop { header }),
                Some(0) => return Err(WcetError::ZeroBound { header }),
                Some(&m) => m,
            };
        }
        // Innermost first; the header's address breaks ties for a deterministic order.
        let mut by_size: Vec<usize> = (0..loops.len()).collect();
        by_size.sort_by_key(|&i| (loops[i].size, blocks[loops[i].header].start));

        // 4. Collapse loops, innermost first, then the function body.
        let mut owner: Vec<Option<usize>> = vec![None; n];
        for &li in &by_size {
            let h = loops[li].header;
            let region = Acyclic {
                blocks: &blocks,
                loops: &loops,
                owner: &owner,
                header: Some(h),
                member: Some(&loops[li].body),
                unexecuted: &self.bounds.unexecuted,
            };
            let start = Node::Block(h);
            let header_addr = blocks[h].start;
            let iter = region
                .longest(start, Sink::Back)?
                .ok_or(WcetError::Irreducible { addr: header_addr })?;
            let sinks = region.sinks(start)?;
            let bound = loops[li].bound as u64;
            let mut exits = Vec::new();
            for s in sinks {
                let Sink::Exit(t) = s else { continue };
                if let Some((c, p)) = region.longest(start, s)? {
                    let mut path =
                        Vec::with_capacity(iter.1.len() * (bound as usize - 1) + p.len());
                    for _ in 1..bound {
                        path.extend_from_slice(&iter.1);
                    }
                    path.extend_from_slice(&p);
                    exits.push((
                        t,
                        (bound - 1).saturating_mul(iter.0).saturating_add(c),
                        path,
                    ));
                }
            }
            if exits.is_empty() {
                return Err(WcetError::NoExit {
                    header: header_addr,
                });
            }
            loops[li].exits = exits;
            for (b, o) in owner.iter_mut().enumerate() {
                if loops[li].body[b] {
                    *o = Some(li);
                }
            }
        }
        let region = Acyclic {
            blocks: &blocks,
            loops: &loops,
            owner: &owner,
            header: None,
            member: None,
            unexecuted: &self.bounds.unexecuted,
        };
        let start = match owner[root] {
            Some(l) => Node::Loop(l),
            None => Node::Block(root),
        };
        let (cycles, path) = region
            .longest(start, Sink::Exit(None))?
            .ok_or(WcetError::NoReturn { entry })?;
        let blocks = blocks
            .iter()
            .map(|b| BlockCost {
                start: b.start,
                end: b.end,
                cycles: b.body + b.edges.iter().map(|e| e.cost).max().unwrap_or(0),
            })
            .collect();
        Ok(Wcet {
            cycles,
            path,
            blocks,
            calls,
        })
    }

    /// Cost of a non-branching instruction at `addr`, its data access priced by region.
    fn cost(&self, addr: u32, instr: &Instr, consts: &Consts) -> u64 {
        use Instr::*;
        let region = |known: Option<u32>| -> Region {
            if let Some(&r) = self.bounds.accesses.get(&addr) {
                return r;
            }
            match known {
                Some(a) => Region::of(a),
                None => self.bounds.unknown_access,
            }
        };
        let single = |region: Region, store: bool| -> u64 {
            let c = timing::cycles(instr, false, region == Region::IoPort) as u64;
            c + match (region, store) {
                (Region::Apb, false) => APB_LOAD_WAIT as u64,
                (Region::Apb, true) => APB_STORE_WAIT as u64,
                _ => 0,
            }
        };
        match *instr {
            LdrLit { imm, .. } => {
                let a = (addr.wrapping_add(4) & !3).wrapping_add(imm as u32);
                single(region(Some(a)), false)
            }
            // The stack is in SRAM: SP-relative accesses are memory unless declared.
            MemImm { op, rn: 13, .. } => single(
                self.bounds
                    .accesses
                    .get(&addr)
                    .copied()
                    .unwrap_or(Region::Memory),
                op.is_store(),
            ),
            MemImm { op, rn, imm, .. } => {
                let a = consts.get(rn).map(|b| b.wrapping_add(imm as u32));
                single(region(a), op.is_store())
            }
            MemReg { op, rn, rm, .. } => {
                let a = match (consts.get(rn), consts.get(rm)) {
                    (Some(x), Some(y)) => Some(x.wrapping_add(y)),
                    _ => None,
                };
                single(region(a), op.is_store())
            }
            Ldm { rn, list } | Stm { rn, list } => {
                let c = timing::cycles(instr, false, false) as u64;
                let r = match self.bounds.accesses.get(&addr) {
                    Some(&r) => r,
                    None => consts.get(rn).map(Region::of).unwrap_or(
                        // Only APB adds wait states to a multiple transfer.
                        if self.bounds.unknown_access == Region::Apb {
                            Region::Apb
                        } else {
                            Region::Memory
                        },
                    ),
                };
                let wait = if matches!(instr, Ldm { .. }) {
                    APB_LOAD_WAIT
                } else {
                    APB_STORE_WAIT
                };
                c + if r == Region::Apb {
                    wait as u64 * list.count_ones() as u64
                } else {
                    0
                }
            }
            _ => timing::cycles(instr, false, false) as u64,
        }
    }
}

/// Known register values inside a basic block (for data-access regions).
struct Consts([Option<u32>; 16]);

impl Consts {
    fn new() -> Self {
        Consts([None; 16])
    }
    fn get(&self, r: u8) -> Option<u32> {
        if r < 13 {
            self.0[r as usize]
        } else {
            None
        }
    }
    fn set(&mut self, r: u8, v: Option<u32>) {
        self.0[(r & 15) as usize] = v;
    }
    /// Updates the known values after `instr` at `addr` executes.
    fn step(&mut self, code: &dyn Code, addr: u32, instr: &Instr) {
        use Instr::*;
        let pc_al = addr.wrapping_add(4) & !3;
        match *instr {
            MovImm { rd, imm } => self.set(rd, Some(imm as u32)),
            LdrLit { rt, imm } => self.set(rt, code.word(pc_al.wrapping_add(imm as u32))),
            Adr { rd, imm } => self.set(rd, Some(pc_al.wrapping_add(imm as u32))),
            AddImm { rd, rn, imm } => {
                self.set(rd, self.get(rn).map(|v| v.wrapping_add(imm as u32)))
            }
            SubImm { rd, rn, imm } => {
                self.set(rd, self.get(rn).map(|v| v.wrapping_sub(imm as u32)))
            }
            LslImm { rd, rm, imm } => self.set(rd, self.get(rm).map(|v| v << (imm & 31))),
            LsrImm { rd, rm, imm } => self.set(
                rd,
                self.get(rm).map(|v| if imm >= 32 { 0 } else { v >> imm }),
            ),
            AddReg { rd, rn, rm } => {
                let v = match (self.get(rn), self.get(rm)) {
                    (Some(a), Some(b)) => Some(a.wrapping_add(b)),
                    _ => None,
                };
                self.set(rd, v)
            }
            MovHi { rd, rm } => self.set(rd, self.get(rm)),
            // A special register (and the flags): no general register.
            Msr { .. } => {}
            // Every other instruction: what it writes is unknown (`effects`; SP, r13, is
            // never known). Branches, calls and traps end a block or are errors; forget
            // everything.
            _ => match effects::effect(instr) {
                Some(e) => {
                    for r in (0..16).filter(|r| e.writes & 1 << r != 0) {
                        self.set(r, None);
                    }
                }
                None => *self = Consts::new(),
            },
        }
    }
}

/// Depth-first order of the blocks reachable from block `root` (the entry's): reverse
/// postorder, `root` first.
fn dfs_order(blocks: &[Block], root: usize) -> Vec<usize> {
    let n = blocks.len();
    let mut seen = vec![false; n];
    let mut post = Vec::with_capacity(n);
    let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
    seen[root] = true;
    while let Some(&mut (b, ref mut i)) = stack.last_mut() {
        let edges = &blocks[b].edges;
        if *i < edges.len() {
            let e = edges[*i];
            *i += 1;
            if let Some(t) = e.to {
                if !seen[t] {
                    seen[t] = true;
                    stack.push((t, 0));
                }
            }
        } else {
            post.push(b);
            stack.pop();
        }
    }
    post.reverse();
    post
}

/// Immediate dominators (Cooper, Harvey, Kennedy, "A Simple, Fast Dominance Algorithm").
fn dominators(order: &[usize], rpo: &[usize], preds: &[Vec<usize>], root: usize) -> Vec<usize> {
    let n = rpo.len();
    let mut idom = vec![usize::MAX; n];
    idom[root] = root;
    let mut changed = true;
    while changed {
        changed = false;
        for &b in order.iter().skip(1) {
            let mut new = usize::MAX;
            for &p in &preds[b] {
                if idom[p] == usize::MAX {
                    continue;
                }
                new = if new == usize::MAX {
                    p
                } else {
                    let (mut x, mut y) = (p, new);
                    while x != y {
                        while rpo[x] > rpo[y] {
                            x = idom[x];
                        }
                        while rpo[y] > rpo[x] {
                            y = idom[y];
                        }
                    }
                    x
                };
            }
            if new != idom[b] {
                idom[b] = new;
                changed = true;
            }
        }
    }
    idom
}

/// A loop body (or the whole function) with its inner loops collapsed: an acyclic graph.
struct Acyclic<'a> {
    blocks: &'a [Block],
    loops: &'a [Loop],
    owner: &'a [Option<usize>],
    /// The loop header (edges to it are back edges), or `None` for the function.
    header: Option<usize>,
    /// Blocks of the loop (`None`: every block).
    member: Option<&'a Vec<bool>>,
    /// Start addresses of blocks no counted path may enter ([`Bounds::unexecuted`]).
    unexecuted: &'a HashSet<u32>,
}

/// An edge of a region: target, cycles, path segment the source node contributes.
type OutEdge = (Target, u64, Vec<u32>);

impl Acyclic<'_> {
    fn target(&self, to: Option<usize>) -> Result<Target, WcetError> {
        let Some(t) = to else {
            return Ok(Target::Sink(Sink::Exit(None)));
        };
        if Some(t) == self.header {
            return Ok(Target::Sink(Sink::Back));
        }
        if let Some(m) = self.member {
            if !m[t] {
                return Ok(Target::Sink(Sink::Exit(Some(t))));
            }
        }
        Ok(Target::Node(match self.owner[t] {
            Some(l) => {
                if self.loops[l].header != t {
                    return Err(WcetError::Irreducible {
                        addr: self.blocks[t].start,
                    });
                }
                Node::Loop(l)
            }
            None => Node::Block(t),
        }))
    }

    fn out(&self, node: Node) -> Result<Vec<OutEdge>, WcetError> {
        match node {
            Node::Block(b) => {
                let blk = &self.blocks[b];
                blk.edges
                    .iter()
                    .map(|e| Ok((self.target(e.to)?, blk.body + e.cost, vec![blk.start])))
                    .collect()
            }
            Node::Loop(l) => self.loops[l]
                .exits
                .iter()
                .map(|(t, c, p)| Ok((self.target(*t)?, *c, p.clone())))
                .collect(),
        }
    }

    /// Nodes reachable from `start`, in topological order, with their out-edges.
    fn topo(&self, start: Node) -> Result<Vec<(Node, Vec<OutEdge>)>, WcetError> {
        let mut state: HashMap<Node, u8> = HashMap::new(); // 1 on stack, 2 done
        let mut post: Vec<(Node, Vec<OutEdge>)> = Vec::new();
        let mut stack: Vec<(Node, Vec<OutEdge>, usize)> = vec![(start, self.out(start)?, 0)];
        state.insert(start, 1);
        while let Some(top) = stack.last_mut() {
            if top.2 < top.1.len() {
                let t = top.1[top.2].0;
                top.2 += 1;
                if let Target::Node(m) = t {
                    match state.get(&m) {
                        Some(1) => {
                            let addr = match m {
                                Node::Block(b) => self.blocks[b].start,
                                Node::Loop(l) => self.blocks[self.loops[l].header].start,
                            };
                            return Err(WcetError::Irreducible { addr });
                        }
                        Some(_) => {}
                        None => {
                            state.insert(m, 1);
                            let o = self.out(m)?;
                            stack.push((m, o, 0));
                        }
                    }
                }
            } else {
                let (node, edges, _) = stack.pop().expect("non-empty");
                state.insert(node, 2);
                post.push((node, edges));
            }
        }
        post.reverse();
        Ok(post)
    }

    /// The sinks reachable from `start`.
    fn sinks(&self, start: Node) -> Result<BTreeSet<Sink>, WcetError> {
        let mut s = BTreeSet::new();
        for (_, edges) in self.topo(start)? {
            for (t, _, _) in edges {
                if let Target::Sink(k) = t {
                    s.insert(k);
                }
            }
        }
        Ok(s)
    }

    /// The longest path from `start` to `sink`: cycles and block path, `None` if the sink
    /// is unreachable.
    fn longest(&self, start: Node, sink: Sink) -> Result<Option<(u64, Vec<u32>)>, WcetError> {
        let topo = self.topo(start)?;
        let barred = |n: &Node| matches!(*n, Node::Block(i) if self.unexecuted.contains(&self.blocks[i].start));
        if barred(&start) {
            return Ok(None);
        }
        // best[node] = (cycles to the sink, index of the chosen edge).
        let mut best: HashMap<Node, (u64, usize)> = HashMap::new();
        for (node, edges) in topo.iter().rev() {
            let mut b: Option<(u64, usize)> = None;
            for (i, (t, c, _)) in edges.iter().enumerate() {
                let v = match t {
                    Target::Sink(k) if *k == sink => Some(*c),
                    Target::Sink(_) => None,
                    Target::Node(m) if barred(m) => None,
                    // Saturating: an unbounded-looking intermediate (a long branch analysed as a
                    // call, before it is declared) must not wrap into a small bound.
                    Target::Node(m) => best.get(m).map(|(x, _)| x.saturating_add(*c)),
                };
                if let Some(v) = v {
                    if b.is_none_or(|(x, _)| v > x) {
                        b = Some((v, i));
                    }
                }
            }
            if let Some(b) = b {
                best.insert(*node, b);
            }
        }
        let Some(&(cycles, _)) = best.get(&start) else {
            return Ok(None);
        };
        let edges_of: HashMap<Node, &Vec<OutEdge>> = topo.iter().map(|(n, e)| (*n, e)).collect();
        let mut path = Vec::new();
        let mut node = start;
        loop {
            let (_, i) = best[&node];
            let (t, _, seg) = &edges_of[&node][i];
            path.extend_from_slice(seg);
            match t {
                Target::Node(m) => node = *m,
                Target::Sink(_) => break,
            }
        }
        Ok(Some((cycles, path)))
    }
}
