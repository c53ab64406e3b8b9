//! The replay's vocabulary, shared by every device that a window's replay or a period memo
//! (`board/io_window.rs`) takes apart: time bases ([`Rebase`]: a recorded state's cycles
//! moved to where it is given again).

/// Cycles moved from one time base to another (a window's start to a period memo's and
/// back, `crate::io::Io::rebased`): `from` goes to `to`, and the values no cycle can take — 0 (the
/// DMA's ports before their first transfer, a state machine held nowhere) and `u64::MAX`
/// (a bank no DMA master has claimed) — stay.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rebase {
    pub from: u64,
    pub to: u64,
}

impl Rebase {
    /// The time base the memo keeps its states at: far from 0 and `u64::MAX` either way,
    /// so that no rebased cycle meets those two.
    pub const MEMO: u64 = 1 << 62;

    /// `v` in the new time base.
    pub fn at(self, v: u64) -> u64 {
        match v {
            0 | u64::MAX => v,
            _ => v.wrapping_sub(self.from).wrapping_add(self.to),
        }
    }

    /// The move back.
    pub fn back(self) -> Rebase {
        Rebase {
            from: self.to,
            to: self.from,
        }
    }
}
