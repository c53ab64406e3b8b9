//! Core 1's launch: the boot ROM's wait loop and the FIFO handshake that starts core 1.

use super::*;
/// Where core 1's boot ROM is in its wait loop (pico-bootrom `bootrom/bootrom_rt0.S`,
/// `wait_for_vector`; RP2040 datasheet 2.8.2): the next word it waits for, the VTOR and
/// stack pointer received so far, and a word it could not yet send because core 0's RX
/// FIFO was full (the ROM waits in `WFE` for room, `send_and_then_again`).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Launch {
    /// 0: the command 1; 1: the vector table; 2: the stack pointer; 3: the entry point;
    /// 4: launching once the entry point's echo is sent.
    step: usize,
    vtor: u32,
    sp: u32,
    entry: u32,
    unsent: Option<u32>,
}

impl Machine {
    /// Core 1's boot ROM at `core_0_handshake_loop`: drain its RX FIFO, send 0 to core 0
    /// and wait for the command 1.
    pub(crate) fn launch_handshake(&mut self) {
        // The drain reads while VLD is set: it never underflows.
        while self.system.sio.fifo_status(1) & 1 != 0 {
            self.system.sio.fifo_pop(1);
        }
        if let Some(l) = &mut self.launch {
            *l = Launch {
                unsent: Some(0),
                ..Launch::default()
            };
        }
        self.launch_send();
    }

    /// Sends core 1's pending word to core 0 if its RX FIFO has room, then `SEV` (as the
    /// ROM's `send_and_then` does). False while the word waits for room.
    pub(crate) fn launch_send(&mut self) -> bool {
        let Some(l) = &mut self.launch else {
            return true;
        };
        let Some(word) = l.unsent else {
            return true;
        };
        if self.system.sio.fifo_status(1) & 2 == 0 {
            return false;
        }
        l.unsent = None;
        self.system.sio.fifo_push(1, word);
        self.cores[0].event = true;
        true
    }

    /// Core 1's boot ROM reacting to what core 0 sent, word by word (pico-bootrom
    /// `bootrom_rt0.S`: `wait_for_vector`, `send_and_then`, `receive_and_check_zero`;
    /// datasheet 2.8.2): a 0 sends it back to the handshake (drain, send 0); in the first
    /// step anything but 1 does too; otherwise it takes the word (VTOR, then SP, then the
    /// entry point), echoes it, and after echoing the entry point starts core 1 there
    /// with that VTOR and SP. The ROM's own instructions are not timed: each reaction
    /// happens when core 0 next runs (about a dozen cycles per word on the chip).
    pub(crate) fn poll_launch(&mut self) {
        loop {
            if !self.launch_send() {
                return;
            }
            let Some(l) = self.launch else { return };
            if l.step == 4 {
                self.start_core_at(1, l.entry, l.sp, l.vtor);
                return;
            }
            if self.system.sio.fifo_status(1) & 1 == 0 {
                return;
            }
            let Some(word) = self.system.sio.fifo_pop(1) else {
                return;
            };
            if word == 0 || (l.step == 0 && word != 1) {
                self.launch_handshake();
                continue;
            }
            let mut next = Launch {
                step: l.step + 1,
                unsent: Some(word),
                ..l
            };
            match l.step {
                1 => next.vtor = word,
                2 => next.sp = word,
                3 => next.entry = word,
                _ => {}
            }
            self.launch = Some(next);
        }
    }
}
