//! The RP2040 single-cycle IO block (SIO, 0xd0000000; RP2040 datasheet section 2.3).
//!
//! SIO sits on each core's single-cycle I/O port, so its accesses cost 1 cycle and never
//! contend. Some of it is per core (CPUID, the divider, which end of the FIFOs you see) and
//! some is shared (spinlocks), hence [`Sio`] holds per-core arrays indexed by the accessing
//! core. The divider computes its result eagerly when an operand is written and records the
//! cycle from which reads see it ([`Divider::ready_at`]); GPIO and the interpolators are not
//! modelled (reads return 0, writes are ignored).

use tactus_isa::timing::DIVIDER_LATENCY;
use tactus_rp2040::sio::{reg, FIFO_DEPTH};

/// One core's hardware divider (datasheet 2.3.1.5).
///
/// Early reads: the datasheet says results read before the 8 cycles have elapsed are not
/// valid (the hardware shows the serial divider's intermediate state). We return the
/// *previous* results (those before the operand write) and READY = 0, which is deterministic
/// and makes firmware that reads too early visibly wrong in tests.
#[derive(Clone, Debug, Default)]
pub struct Divider {
    dividend: u32,
    divisor: u32,
    signed: bool,
    quotient: u32,
    remainder: u32,
    old_quotient: u32,
    old_remainder: u32,
    /// First cycle at which reads see the new result: the operand store's cycle + 1 +
    /// [`DIVIDER_LATENCY`], i.e. 8 full cycles must pass between the store and the load.
    pub ready_at: u64,
    dirty: bool,
}

impl Divider {
    fn start(&mut self, now: u64) {
        if now >= self.ready_at {
            self.old_quotient = self.quotient;
            self.old_remainder = self.remainder;
        }
        let (q, r) = if self.signed {
            let (n, d) = (self.dividend as i32, self.divisor as i32);
            if d == 0 {
                // Datasheet 2.3.1.5: division by zero gives quotient -1 (or +1 for a negative
                // dividend) and the dividend as remainder.
                ((if n < 0 { 1 } else { -1i32 }) as u32, n as u32)
            } else {
                (n.wrapping_div(d) as u32, n.wrapping_rem(d) as u32)
            }
        } else {
            match (
                self.dividend.checked_div(self.divisor),
                self.dividend.checked_rem(self.divisor),
            ) {
                (Some(q), Some(r)) => (q, r),
                _ => (u32::MAX, self.dividend),
            }
        };
        self.quotient = q;
        self.remainder = r;
        self.dirty = true;
        self.ready_at = now + 1 + DIVIDER_LATENCY as u64;
    }

    fn results(&self, now: u64) -> (u32, u32) {
        if now >= self.ready_at {
            (self.quotient, self.remainder)
        } else {
            (self.old_quotient, self.old_remainder)
        }
    }
}

/// The SIO block shared by both cores.
#[derive(Clone, Debug, Default)]
pub struct Sio {
    /// `fifo[c]` holds words written by core `c` for the other core to read.
    fifo: [std::collections::VecDeque<u32>; 2],
    /// Sticky FIFO error flags per reading/writing core: WOF (bit 2), ROE (bit 3).
    fifo_err: [u32; 2],
    spinlocks: u32,
    /// Each core's divider.
    pub divider: [Divider; 2],
}

impl Sio {
    /// FIFO_ST as seen by `core`.
    pub fn fifo_status(&self, core: usize) -> u32 {
        let vld = !self.fifo[1 - core].is_empty() as u32;
        let rdy = (self.fifo[core].len() < FIFO_DEPTH) as u32;
        vld | (rdy << 1) | self.fifo_err[core]
    }

    /// Pushes a word into the FIFO from `core` to the other core (as a FIFO_WR store does);
    /// returns false (and sets WOF) when full.
    pub fn fifo_push(&mut self, core: usize, value: u32) -> bool {
        if self.fifo[core].len() < FIFO_DEPTH {
            self.fifo[core].push_back(value);
            true
        } else {
            self.fifo_err[core] |= 4;
            false
        }
    }

    /// Pops a word from `core`'s RX FIFO (as a FIFO_RD load does); `None` (and ROE) if empty.
    pub fn fifo_pop(&mut self, core: usize) -> Option<u32> {
        let v = self.fifo[1 - core].pop_front();
        if v.is_none() {
            self.fifo_err[core] |= 8;
        }
        v
    }

    /// SIO_IRQ_PROCn level for `core`: RX data valid or a sticky error (datasheet 2.3.1.4).
    pub fn irq(&self, core: usize) -> bool {
        !self.fifo[1 - core].is_empty() || self.fifo_err[core] != 0
    }

    /// Reads register `offset` for `core` at cycle `now`; `None` if unmapped.
    pub fn read(&mut self, core: usize, now: u64, offset: u32) -> Option<u32> {
        Some(match offset {
            reg::CPUID => core as u32,
            0x004..=0x04c => 0, // GPIO: not modelled
            reg::FIFO_ST => self.fifo_status(core),
            reg::FIFO_RD => self.fifo_pop(core).unwrap_or(0),
            reg::SPINLOCK_ST => self.spinlocks,
            reg::DIV_UDIVIDEND | reg::DIV_SDIVIDEND => self.divider[core].dividend,
            reg::DIV_UDIVISOR | reg::DIV_SDIVISOR => self.divider[core].divisor,
            reg::DIV_QUOTIENT => {
                let d = &mut self.divider[core];
                d.dirty = false;
                d.results(now).0
            }
            reg::DIV_REMAINDER => self.divider[core].results(now).1,
            reg::DIV_CSR => {
                let d = &self.divider[core];
                (now >= d.ready_at) as u32 | ((d.dirty as u32) << 1)
            }
            0x080..=0x0fc => 0, // interpolators: not modelled
            reg::SPINLOCK0..=0x17c => {
                let bit = 1u32 << ((offset - reg::SPINLOCK0) / 4);
                if self.spinlocks & bit != 0 {
                    0
                } else {
                    self.spinlocks |= bit;
                    bit
                }
            }
            _ => return None,
        })
    }

    /// Writes register `offset` for `core` at cycle `now`; false if unmapped.
    pub fn write(&mut self, core: usize, now: u64, offset: u32, value: u32) -> bool {
        match offset {
            0x004..=0x04c => {}
            reg::FIFO_ST => self.fifo_err[core] = 0,
            reg::FIFO_WR => {
                self.fifo_push(core, value);
            }
            reg::DIV_UDIVIDEND | reg::DIV_UDIVISOR | reg::DIV_SDIVIDEND | reg::DIV_SDIVISOR => {
                let d = &mut self.divider[core];
                if offset & 4 == 0 {
                    d.dividend = value;
                } else {
                    d.divisor = value;
                }
                d.signed = offset >= reg::DIV_SDIVIDEND;
                d.start(now);
            }
            reg::DIV_QUOTIENT | reg::DIV_REMAINDER => {
                // Writing a result register restores saved state: valid at once.
                let d = &mut self.divider[core];
                let (q, r) = d.results(now);
                if offset == reg::DIV_QUOTIENT {
                    (d.quotient, d.remainder) = (value, r);
                } else {
                    (d.quotient, d.remainder) = (q, value);
                }
                d.ready_at = 0;
                d.dirty = true;
            }
            0x080..=0x0fc => {}
            reg::SPINLOCK0..=0x17c => {
                self.spinlocks &= !(1u32 << ((offset - reg::SPINLOCK0) / 4));
            }
            _ => return false,
        }
        true
    }
}
