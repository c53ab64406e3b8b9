//! Based memos (module documentation of [`super`], "Based memos"): a call's loads through
//! a register among r0-r3 that it reads only as their base, compared where the register
//! points now ([`Based`]), and where they and the call's I/O accesses lie for each of the
//! last deltas ([`Moved`]).

use super::*;

/// A word a based memo's call loaded through its base: its address at the recording
/// (word-aligned), its bank, and the bytes loaded (mask, values).
#[derive(Clone, Copy, Debug)]
pub(super) struct BasedWord {
    pub(super) addr: u32,
    /// Its SRAM offset at the recording.
    pub(super) off: u32,
    pub(super) bank: u8,
    pub(super) mask: u32,
    pub(super) value: u32,
}

/// The base of `rec`'s memo, if it has one: the lowest register still among its
/// candidates ([`Recording::bases`]) that the call read, when its loads through it were
/// none from a page of code, and every word they read lies apart from the call's other
/// accesses (so that, moved, none of them can meet a store of the call).
pub(super) fn based_of(rec: &Recording) -> Option<Based> {
    let reg = (0..4u8).find(|&r| (rec.bases & rec.live_regs) >> r & 1 != 0)?;
    // The loads through it: their places in the log (ascending) and addresses.
    let via: Vec<(usize, u32)> = (rec.log_via.iter())
        .filter(|x| x.1 == reg)
        .map(|&(i, _, addr)| (i as usize, addr))
        .collect();
    let mut words: Vec<BasedWord> = Vec::new();
    for &(i, addr) in &via {
        let a = &rec.log[i];
        if a.code || a.store {
            return None;
        }
        let (word, shift) = (addr & !3, 8 * (addr & 3));
        let mask = (u32::MAX >> (32 - 8 * u32::from(a.size))) << shift;
        let value = (a.value << shift) & mask;
        match words.iter_mut().find(|w| w.addr == word) {
            Some(w) => {
                w.mask |= mask;
                w.value = w.value & !mask | value;
            }
            None => words.push(BasedWord {
                addr: word,
                off: a.off & !3,
                bank: sram_bank(a.off & !3) as u8,
                mask,
                value,
            }),
        }
    }
    if words.is_empty() {
        return None;
    }
    let through = |i: usize| via.binary_search_by_key(&i, |x| x.0).is_ok();
    let mut touched: Vec<u32> = (rec.log.iter().enumerate())
        .filter(|&(i, _)| !through(i))
        .flat_map(|(_, a)| {
            let last = a.off + u32::from(a.size.max(1)) - 1;
            [a.off & !3, last & !3]
        })
        .collect();
    touched.sort_unstable();
    touched.dedup();
    let apart = (via.iter()).all(|&(i, _)| touched.binary_search(&(rec.log[i].off & !3)).is_err());
    let io = (rec.io_via.iter())
        .filter(|x| x.1 == reg)
        .map(|&(i, _, addr)| (i, addr))
        .collect();
    apart.then_some(Based {
        reg,
        at: rec.entry.r[reg as usize],
        words,
        touched,
        io,
        moved: Vec::new(),
    })
}

/// A based memo's base (module documentation, "Based memos"): the register, its value at
/// the recording, the words loaded through it, the SRAM words the call's other accesses
/// touched (offsets, sorted: a moved word may be none of them), and of the memo's I/O
/// accesses those loaded through it (index, address at the recording); and where those
/// lie for the last few deltas the base moved by ([`Moved`]).
#[derive(Clone, Debug)]
pub(super) struct Based {
    pub(super) reg: u8,
    pub(super) at: u32,
    pub(super) words: Vec<BasedWord>,
    pub(super) touched: Vec<u32>,
    pub(super) io: Vec<(u32, u32)>,
    pub(super) moved: Vec<Moved>,
}

/// The most deltas a [`Based`] keeps the places of: the converter drivers' ring of three
/// results buffers gives a key's base two deltas besides 0.
pub(super) const MOVED: usize = 4;

/// Where a based memo's words and I/O accesses lie with its base moved by `delta` bytes
/// (none of it depends on the SRAM's contents: worked out once per delta, not per call).
#[derive(Clone, Debug)]
pub(super) struct Moved {
    pub(super) delta: u32,
    /// The words' SRAM offsets (in [`Based::words`]' order), each in its bank at the
    /// recording and apart from the call's other accesses; `None` when one is not (or
    /// the delta is not a whole number of words): the memo does not match.
    pub(super) offs: Option<Vec<u32>>,
    /// One past the last byte of those words.
    pub(super) end: usize,
    /// The I/O accesses loaded through the base: (index in [`Memo::io`], SRAM offset),
    /// those whose moved address is in the SRAM.
    pub(super) io: Vec<(u32, u32)>,
}

impl Based {
    /// Where the words and I/O accesses lie with the base moved by `delta` (`delta` not 0):
    /// kept for the last [`MOVED`] deltas, the oldest replaced first. Returns its index
    /// in [`Based::moved`].
    pub(super) fn moved(&mut self, delta: u32) -> usize {
        if let Some(i) = self.moved.iter().position(|m| m.delta == delta) {
            return i;
        }
        let offs = (self.words.iter())
            .map(|w| {
                let (off, bank) = sram_location(w.addr.wrapping_add(delta))?;
                let apart = self.touched.binary_search(&(off as u32)).is_err();
                (bank == w.bank as usize && apart).then_some(off as u32)
            })
            .collect::<Option<Vec<u32>>>()
            .filter(|_| delta & 3 == 0);
        let end = (offs.iter().flatten())
            .map(|&o| o as usize + 4)
            .max()
            .unwrap_or(0);
        let io = (self.io.iter())
            .filter_map(|&(i, addr)| {
                sram_location(addr.wrapping_add(delta)).map(|(off, _)| (i, off as u32))
            })
            .collect();
        let m = Moved {
            delta,
            offs,
            end,
            io,
        };
        match self.moved.len() < MOVED {
            true => {
                self.moved.push(m);
                self.moved.len() - 1
            }
            false => {
                self.moved.rotate_left(1);
                self.moved[MOVED - 1] = m;
                MOVED - 1
            }
        }
    }

    /// Whether the words loaded through the base, moved by `delta` bytes (the base's
    /// value now less `at`), hold their bytes in `sram`, each in its bank and apart from
    /// the call's other accesses.
    #[inline]
    pub(super) fn matches(&mut self, delta: u32, sram: &[u8]) -> bool {
        if delta == 0 {
            return self.words.iter().all(|w| {
                w.off as usize + 4 <= sram.len()
                    // SAFETY: `off + 4 <= sram.len()`, checked above.
                    && unsafe { peek(sram, w.off) } & w.mask == w.value
            });
        }
        self.matches_moved(delta, sram)
    }

    /// [`Based::matches`] with `delta` not 0.
    #[inline(never)]
    fn matches_moved(&mut self, delta: u32, sram: &[u8]) -> bool {
        let i = self.moved(delta);
        let (words, m) = (&self.words, &self.moved[i]);
        m.end <= sram.len()
            && m.offs.as_ref().is_some_and(|offs| {
                (words.iter().zip(offs))
                    // SAFETY: every offset + 4 is at most `m.end`, checked above.
                    .all(|(w, &off)| unsafe { peek(sram, off) } & w.mask == w.value)
            })
    }
}
