//! Shared by the fuzz harnesses (`compiler/tests/fuzz_*.rs`, `runtime/tests/fuzz_{midi,toml}.rs`,
//! `emulator/tests/fuzz_elf.rs`): byte-level mutations of seed files, the case count, and
//! the runner, a counting global allocator, so each case can assert bounded time and bounded memory.
//!
//! Included with `#[path = …] mod fuzz;` by each harness, which is then the only test in
//! its binary (the peak counter is global). `TACTUS_FUZZ_CASES=100000` runs that many
//! cases; without it, [`cases`] gives the harness's CI count.

#![allow(dead_code)]

use proptest::prelude::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// The system allocator, counting live bytes and their peak.
pub struct PeakAlloc;

/// The most live heap a harness may hold, bytes: the CLI's `ulimit -v 4000000` less room
/// for code and stacks.
pub const HEAP_CAP: usize = 3 << 30;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for PeakAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // Over the cap a case has failed its memory bound: refuse (the process aborts
        // naming the size) rather than let the machine's OOM killer end it unnamed.
        if LIVE.load(Ordering::Relaxed).saturating_add(layout.size()) > HEAP_CAP {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOC: PeakAlloc = PeakAlloc;

/// The number of cases: `TACTUS_FUZZ_CASES`, or `ci` without it.
pub fn cases(ci: u32) -> u32 {
    std::env::var("TACTUS_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(ci)
}

/// A proptest runner for `cases(ci)` cases, with no failure persistence (a failing case is
/// printed; the seeds are the project's files), and that case count.
pub fn runner(ci: u32) -> (proptest::test_runner::TestRunner, u32) {
    let cases = cases(ci);
    let config = proptest::test_runner::Config {
        cases,
        failure_persistence: None,
        ..proptest::test_runner::Config::default()
    };
    (proptest::test_runner::TestRunner::new(config), cases)
}

/// Runs `f`, returning its result, its wall time and the peak of live heap bytes above
/// what was live before it.
pub fn measured<T>(f: impl FnOnce() -> T) -> (T, Duration, usize) {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let t = Instant::now();
    let r = f();
    let dt = t.elapsed();
    let peak = PEAK.load(Ordering::Relaxed).saturating_sub(base);
    (r, dt, peak)
}

/// One edit of a byte string; positions are taken modulo the length.
#[derive(Clone, Debug)]
pub enum Edit {
    /// Overwrite one byte.
    Set(usize, u8),
    /// Remove `len` bytes.
    Delete(usize, usize),
    /// Repeat a slice `times` times in place (long chains, deep nests, big counts).
    Repeat(usize, usize, usize),
    /// Insert bytes.
    Insert(usize, Vec<u8>),
    /// Overwrite four bytes with a little- or big-endian extreme word.
    Word(usize, u32, bool),
    /// Cut the input here.
    Truncate(usize),
    /// Insert bytes at the start of the line holding a position (keeps declarations whole).
    InsertLine(usize, Vec<u8>),
    /// Replace a number (the digits at or after a position) by other digits.
    Number(usize, Vec<u8>),
}

/// Extreme words that sizes, counts and offsets meet.
const WORDS: [u32; 8] = [
    0,
    1,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    0xFFFF,
    0x1000_0000,
    0x0FFF_FFFF,
];

/// A strategy of edit lists; `tokens` are byte strings worth inserting (keywords, numbers).
pub fn edits(tokens: &'static [&'static [u8]]) -> impl Strategy<Value = Vec<Edit>> {
    let edit = prop_oneof![
        4 => (any::<usize>(), any::<u8>()).prop_map(|(p, b)| Edit::Set(p, b)),
        2 => (any::<usize>(), 0usize..64).prop_map(|(p, l)| Edit::Delete(p, l)),
        1 => (any::<usize>(), 1usize..48, 1usize..400).prop_map(|(p, l, t)| Edit::Repeat(p, l, t)),
        3 => (any::<usize>(), prop::sample::select(tokens)).prop_map(|(p, t)| Edit::Insert(p, t.to_vec())),
        2 => (any::<usize>(), prop::sample::select(&WORDS[..]), any::<bool>()).prop_map(|(p, w, be)| Edit::Word(p, w, be)),
        1 => any::<usize>().prop_map(Edit::Truncate),
    ];
    prop::collection::vec(edit, 1..6)
}

/// A strategy of edits that mostly keep a source well-formed: whole lines inserted (from
/// `lines`), numbers replaced (from `numbers`), lines repeated.
pub fn line_edits(
    lines: &'static [&'static [u8]],
    numbers: &'static [&'static [u8]],
) -> impl Strategy<Value = Vec<Edit>> {
    let edit = prop_oneof![
        3 => (any::<usize>(), prop::sample::select(lines)).prop_map(|(p, t)| Edit::InsertLine(p, t.to_vec())),
        3 => (any::<usize>(), prop::sample::select(numbers)).prop_map(|(p, t)| Edit::Number(p, t.to_vec())),
        1 => (any::<usize>(), 1usize..80, 1usize..50).prop_map(|(p, l, t)| Edit::Repeat(p, l, t)),
    ];
    prop::collection::vec(edit, 1..4)
}

/// Applies `edits` to `seed`; the result is at most a few hundred KB longer.
pub fn apply(seed: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut v = seed.to_vec();
    for e in edits {
        let n = v.len().max(1);
        match e {
            Edit::Set(p, b) => {
                if !v.is_empty() {
                    v[p % n] = *b;
                }
            }
            Edit::Delete(p, l) => {
                let s = (p % n).min(v.len());
                let e = (s + l).min(v.len());
                v.drain(s..e);
            }
            Edit::Repeat(p, l, t) => {
                let s = (p % n).min(v.len());
                let e = (s + l).min(v.len());
                let chunk = v[s..e].to_vec();
                let mut rep = Vec::with_capacity(chunk.len() * t);
                for _ in 0..*t {
                    rep.extend_from_slice(&chunk);
                }
                v.splice(e..e, rep);
            }
            Edit::Insert(p, bytes) => {
                let s = (p % (v.len() + 1)).min(v.len());
                v.splice(s..s, bytes.iter().copied());
            }
            Edit::Word(p, w, be) => {
                if v.len() >= 4 {
                    let s = p % (v.len() - 3);
                    let b = if *be {
                        w.to_be_bytes()
                    } else {
                        w.to_le_bytes()
                    };
                    v[s..s + 4].copy_from_slice(&b);
                }
            }
            Edit::Truncate(p) => v.truncate(p % n),
            Edit::InsertLine(p, bytes) => {
                let at = (p % n).min(v.len());
                let s = v[..at]
                    .iter()
                    .rposition(|&b| b == b'\n')
                    .map_or(0, |i| i + 1);
                v.splice(s..s, bytes.iter().copied());
            }
            Edit::Number(p, digits) => {
                let at = (p % n).min(v.len());
                if let Some(s) = v[at..].iter().position(u8::is_ascii_digit).map(|i| at + i) {
                    let e = v[s..]
                        .iter()
                        .position(|b| !(b.is_ascii_digit() || *b == b'.'))
                        .map_or(v.len(), |i| s + i);
                    v.splice(s..e, digits.iter().copied());
                }
            }
        }
    }
    v
}
