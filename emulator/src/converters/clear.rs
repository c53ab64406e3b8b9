//! The DAC's asynchronous clear (its CLR pin), which a watchdog reset pulls
//! (`crate::machine`'s `reset.rs`): apart from the part's SPI model, which never sees it.

use super::{Dac8568, DacUpdate, Recorded};

impl Dac8568 {
    /// The CLR pin's falling edge at `cycle` (SBAS430F, "Clear Code Register and Clear
    /// Pin"): every input and output register to the clear code and any frame under way
    /// abandoned; each output that changes is an update at `cycle`. Our board's design
    /// (docs/firmware.md, the fault table): CLR on a GPIO that a watchdog reset releases to
    /// its pad's pull-down (RP2040 datasheet 2.19.6.3: pads reset with the pull-down on), the
    /// clear code midscale, the board's 0 A ([`crate::machine::Machine`]'s reset).
    pub(crate) fn clear(&mut self, cycle: u64) {
        const MIDSCALE: u16 = 0x8000;
        self.input = [MIDSCALE; 8];
        self.bits = 0;
        self.shift = 0;
        for c in 0..8 {
            if self.output[c] != MIDSCALE {
                self.output[c] = MIDSCALE;
                if !self.is_full() {
                    self.updates.push(DacUpdate {
                        cycle,
                        channel: c as u8,
                        code: MIDSCALE,
                    });
                }
            }
        }
    }
}
