//! One enabled cycle of a state machine (datasheet 3.4, 3.5): the pending delay, or the
//! instruction at PC (or one forced through SMx_INSTR, OUT EXEC or MOV EXEC) with its
//! side-set, stall, wrap and autopull, one function per instruction (3.4.2–3.4.10). While a
//! replay is recorded, each moves its data's lanes with the data and fixes the lanes of data
//! that decides something (`slots.rs`, `crate::lanes`).

use super::*;

impl Pio {
    /// Runs one enabled cycle of state machine `n`, the state machines seeing `gpio`.
    #[inline(always)]
    pub(super) fn execute(&mut self, n: usize, gpio: u32) -> Effects {
        if self.lanes.is_none() {
            return self.execute_with(n, gpio, &mut None);
        }
        let mut lanes = self.lanes.take();
        if let Some(l) = lanes.as_deref_mut() {
            l.pend[n] = CONST;
        }
        let fx = self.execute_with(n, gpio, &mut lanes);
        self.lanes = lanes;
        fx
    }

    /// [`Pio::execute`] with the block's lanes taken out of it (`None` when not kept).
    #[inline(always)]
    pub(super) fn execute_with(
        &mut self,
        n: usize,
        gpio: u32,
        lanes: &mut Option<Box<PioLanes>>,
    ) -> Effects {
        let mut fx = Effects::default();
        let forced = self.sm[n].exec.is_some();
        if self.sm[n].delay > 0 && !forced {
            self.sm[n].stalled = None;
            self.sm[n].delay -= 1;
            self.background_pull(n, lanes.as_deref_mut());
            return fx;
        }
        let ins = match self.sm[n].exec.take() {
            Some(i) => i,
            None => self.instr[self.sm[n].pc as usize],
        };
        self.sm[n].current = ins;
        // Side-set and delay (datasheet 3.5.1): asserted even when the instruction stalls.
        let s = &self.sm[n];
        let (side, delay) = s.side_set(ins);
        if s.side_pindir() {
            fx.side_dirs = side;
        } else {
            fx.side_values = side;
        }
        let done = self.run(n, ins, gpio, &mut fx, lanes);
        let s = &mut self.sm[n];
        s.stalled = matches!(done, Flow::Stall).then_some(fx);
        match done {
            Flow::Stall => {
                // The instruction runs again next time (kept as the forced one if it was).
                if forced {
                    s.exec = Some(ins);
                }
                return fx;
            }
            // An instruction run through SMx_INSTR or EXEC leaves PC as it was, unless it
            // jumps (pico-sdk's pio_sm_set_pins runs SETs this way between init and enable).
            Flow::Next if forced => {}
            Flow::Next => s.advance(),
            Flow::Jump(to) => s.pc = to & 31,
            Flow::Stay => {}
        }
        // OUT EXEC and MOV EXEC ignore their own delay (datasheet 3.4.5.2).
        if !matches!(done, Flow::Stay) {
            s.delay = delay;
        }
        fx
    }

    /// Autopull on a cycle that is not an OUT's (datasheet 3.5.4.2).
    pub(super) fn background_pull(&mut self, n: usize, lanes: Option<&mut PioLanes>) {
        let s = &mut self.sm[n];
        if !s.autopull() {
            return;
        }
        if s.osr_count >= s.pull_thresh() {
            if let Some(w) = s.tx.pop() {
                if let Some(l) = lanes {
                    l.sm[n].osr = l.sm[n].tx.pop();
                }
                s.osr = w;
                s.osr_count = 0;
            }
        }
    }

    /// Executes `ins` on state machine `n`; what happens to PC. Its lanes (`lanes`, when
    /// kept) follow each move of data, and data that decides something is fixed.
    pub(super) fn run(
        &mut self,
        n: usize,
        ins: u16,
        gpio: u32,
        fx: &mut Effects,
        lanes: &mut Option<Box<PioLanes>>,
    ) -> Flow {
        let ins = u32::from(ins);
        let op = ins >> 13;
        let in_base = bits(self.sm[n].pinctrl, 15, 5);
        let d = Decoded {
            ins,
            arg1: bits(ins, 5, 3),
            arg2: bits(ins, 0, 5),
            gpio,
            pins_in: gpio.rotate_right(in_base),
            in_base,
            sm: n as u32,
        };
        // The lanes kept, with this state machine's and what the pins show it.
        let mut lanes = lanes.as_deref_mut();
        let flow = match op {
            0 => self.jmp(n, &d, lanes.as_deref_mut()),
            1 => self.wait(n, &d, lanes.as_deref_mut()),
            2 => self.in_(n, &d, lanes.as_deref_mut()),
            3 => self.out(n, &d, fx, lanes.as_deref_mut()),
            4 => self.push_pull(n, &d, lanes.as_deref_mut()),
            5 => self.mov(n, &d, fx, lanes.as_deref_mut()),
            6 => self.irq(n, &d, lanes.as_deref_mut()),
            _ => self.set(n, &d, fx, lanes.as_deref_mut()),
        };
        if op != 3 && op != 2 {
            // Every cycle but an OUT's may autopull (PULL and MOV OSR have just set the
            // output count to 0 themselves).
            self.background_pull(n, lanes);
        }
        flow
    }

    /// JMP (datasheet 3.4.2): jump on a condition of X, Y, a pin or the OSR.
    #[inline(always)]
    fn jmp(&mut self, n: usize, d: &Decoded, lanes: Option<&mut PioLanes>) -> Flow {
        let Decoded {
            arg1, arg2, gpio, ..
        } = *d;
        let s = &mut self.sm[n];
        if let Some(l) = lanes {
            let (sl, fixed) = (&mut l.sm[n], &mut l.fixed);
            match arg1 {
                1 | 2 => lanes::fix(&mut sl.x, s.x, u32::MAX, fixed),
                3 | 4 => lanes::fix(&mut sl.y, s.y, u32::MAX, fixed),
                5 => {
                    lanes::fix(&mut sl.x, s.x, u32::MAX, fixed);
                    lanes::fix(&mut sl.y, s.y, u32::MAX, fixed);
                }
                6 => {
                    let pin = bits(s.execctrl, 24, 5);
                    lanes::fix(&mut l.seen, gpio, 1 << pin, fixed);
                }
                _ => {}
            }
        }
        let take = match arg1 {
            0 => true,
            1 => s.x == 0,
            2 => {
                let t = s.x != 0;
                s.x = s.x.wrapping_sub(1);
                t
            }
            3 => s.y == 0,
            4 => {
                let t = s.y != 0;
                s.y = s.y.wrapping_sub(1);
                t
            }
            5 => s.x != s.y,
            6 => gpio & (1 << bits(s.execctrl, 24, 5)) != 0,
            _ => s.osr_count < s.pull_thresh(),
        };
        match take {
            true => Flow::Jump(arg2),
            false => Flow::Next,
        }
    }

    /// WAIT (3.4.3): stall until a GPIO, an input pin or an IRQ flag has the polarity asked.
    #[inline(always)]
    fn wait(&mut self, _n: usize, d: &Decoded, lanes: Option<&mut PioLanes>) -> Flow {
        let Decoded {
            ins,
            arg2,
            gpio,
            pins_in,
            in_base,
            ..
        } = *d;
        let irq_index = |idx: u32| d.irq_index(idx);
        let pins_in_lanes = |l: &PioLanes| lanes::rotr(&l.seen, in_base);
        let pol = ins & 0x80 != 0;
        let idx = arg2;
        if let Some(l) = lanes {
            match bits(ins, 5, 2) {
                0 => lanes::fix(&mut l.seen, gpio, 1 << idx, &mut l.fixed),
                1 => {
                    let mut w = pins_in_lanes(l);
                    lanes::fix(&mut w, pins_in, 1 << idx, &mut l.fixed);
                }
                _ => {}
            }
        }
        let met = match bits(ins, 5, 2) {
            0 => (gpio >> idx) & 1 == u32::from(pol),
            1 => (pins_in >> idx) & 1 == u32::from(pol),
            2 => {
                let f = irq_index(idx);
                let set = self.irq & (1 << f) != 0;
                if pol && set {
                    // WAIT 1 IRQ clears the flag it waited for.
                    self.irq &= !(1 << f);
                }
                set == pol
            }
            _ => true,
        };
        match met {
            true => Flow::Next,
            false => Flow::Stall,
        }
    }

    /// IN (3.4.4): shift bits into the ISR, with autopush.
    #[inline(always)]
    fn in_(&mut self, n: usize, d: &Decoded, mut lanes: Option<&mut PioLanes>) -> Flow {
        let Decoded {
            arg1,
            arg2,
            pins_in,
            in_base,
            ..
        } = *d;
        let pins_in_lanes = |l: &PioLanes| lanes::rotr(&l.seen, in_base);
        let c = count32(arg2);
        let s = &self.sm[n];
        let data = match arg1 {
            0 => pins_in,
            1 => s.x,
            2 => s.y,
            6 => s.isr,
            7 => s.osr,
            _ => 0,
        };
        let after = (s.isr_count + c).min(32);
        if s.autopush() && after >= s.push_thresh() && s.rx_full() {
            Flow::Stall
        } else {
            let s = &mut self.sm[n];
            if let Some(l) = lanes.as_deref_mut() {
                let pins = match arg1 {
                    0 => pins_in_lanes(l),
                    _ => CONST,
                };
                let sl = &mut l.sm[n];
                let data = match arg1 {
                    0 => pins,
                    1 => sl.x,
                    2 => sl.y,
                    6 => sl.isr,
                    7 => sl.osr,
                    _ => CONST,
                };
                sl.isr = shift_in_lanes(&sl.isr, c, &data, s.in_right());
                if s.autopush() && (s.isr_count + c).min(32) >= s.push_thresh() {
                    sl.rx.push(s.rx.len(), sl.isr);
                    sl.isr = CONST;
                }
            }
            s.shift_in(c, data);
            if s.autopush() && s.isr_count >= s.push_thresh() {
                s.rx.push(s.isr);
                s.isr = 0;
                s.isr_count = 0;
            }
            self.background_pull(n, lanes);
            Flow::Next
        }
    }

    /// OUT (3.4.5): shift bits out of the OSR to pins, X, Y, PINDIRS, PC, the ISR or EXEC, with autopull.
    #[inline(always)]
    fn out(
        &mut self,
        n: usize,
        d: &Decoded,
        fx: &mut Effects,
        mut lanes: Option<&mut PioLanes>,
    ) -> Flow {
        let Decoded { arg1, arg2, .. } = *d;
        let c = count32(arg2);
        let s = &mut self.sm[n];
        if s.autopull() && s.osr_count >= s.pull_thresh() {
            // Refill (or wait for data), and stall this cycle either way.
            if let Some(w) = s.tx.pop() {
                if let Some(l) = lanes.as_deref_mut() {
                    l.sm[n].osr = l.sm[n].tx.pop();
                }
                s.osr = w;
                s.osr_count = 0;
            }
            return Flow::Stall;
        }
        let right = s.out_right();
        let data_lanes = lanes.as_deref_mut().map(|l| {
            let sl = &mut l.sm[n];
            let d = out_lanes(&sl.osr, c, right);
            sl.osr = osr_after_lanes(&sl.osr, c, right);
            d
        });
        let data = s.shift_out(c);
        let (out_base, out_count) = (bits(s.pinctrl, 0, 5), bits(s.pinctrl, 20, 6));
        if let (Some(l), Some(mut d)) = (lanes.as_deref_mut(), data_lanes) {
            match arg1 {
                0 => l.pend[n] = map_lanes(out_base, out_count, &d),
                1 => l.sm[n].x = d,
                2 => l.sm[n].y = d,
                // PINDIRS: what the pins are; PC; EXEC: what runs.
                4 => lanes::fix(&mut d, data, u32::MAX, &mut l.fixed),
                5 => lanes::fix(&mut d, data, 31, &mut l.fixed),
                6 => l.sm[n].isr = d,
                7 => lanes::fix(&mut d, data, 0xffff, &mut l.fixed),
                _ => {}
            }
        }
        let flow = match arg1 {
            0..=2 => s.write_pins_x_y(arg1, data, fx),
            4 => {
                fx.dirs = StateMachine::map(out_base, out_count, data);
                Flow::Next
            }
            5 => Flow::Jump(data),
            6 => {
                s.isr = data;
                s.isr_count = c;
                Flow::Next
            }
            7 => {
                s.exec = Some(data as u16);
                s.advance();
                Flow::Stay
            }
            _ => Flow::Next,
        };
        // After the shift, refill at once when data is there (3.5.4.2, lines 11–14).
        if s.autopull() && s.osr_count >= s.pull_thresh() {
            if let Some(w) = s.tx.pop() {
                if let Some(l) = lanes {
                    l.sm[n].osr = l.sm[n].tx.pop();
                }
                s.osr = w;
                s.osr_count = 0;
            }
        }
        flow
    }

    /// PUSH and PULL (3.4.6, 3.4.7): the ISR into the RX FIFO, the TX FIFO into the OSR.
    #[inline(always)]
    fn push_pull(&mut self, n: usize, d: &Decoded, lanes: Option<&mut PioLanes>) -> Flow {
        let Decoded { ins, .. } = *d;
        let if_flag = ins & 0x40 != 0;
        let block = ins & 0x20 != 0;
        let s = &mut self.sm[n];
        let mut sl = lanes.map(|l| &mut l.sm[n]);
        if ins & 0x80 == 0 {
            // PUSH
            if if_flag && s.isr_count < s.push_thresh() {
                Flow::Next
            } else if s.rx_full() {
                match block {
                    true => Flow::Stall,
                    false => {
                        if let Some(sl) = sl {
                            sl.isr = CONST;
                        }
                        s.isr = 0;
                        s.isr_count = 0;
                        Flow::Next
                    }
                }
            } else {
                if let Some(sl) = sl {
                    sl.rx.push(s.rx.len(), sl.isr);
                    sl.isr = CONST;
                }
                s.rx.push(s.isr);
                s.isr = 0;
                s.isr_count = 0;
                Flow::Next
            }
        } else if if_flag && s.osr_count < s.pull_thresh() {
            Flow::Next
        } else {
            // PULL
            match s.tx.pop() {
                Some(w) => {
                    if let Some(sl) = sl.as_deref_mut() {
                        sl.osr = sl.tx.pop();
                    }
                    s.osr = w;
                    s.osr_count = 0;
                    Flow::Next
                }
                None if block => Flow::Stall,
                None => {
                    if let Some(sl) = sl {
                        sl.osr = sl.x;
                    }
                    s.osr = s.x;
                    s.osr_count = 0;
                    Flow::Next
                }
            }
        }
    }

    /// MOV (3.4.8): a source, maybe inverted or bit-reversed, into a destination.
    #[inline(always)]
    fn mov(
        &mut self,
        n: usize,
        d: &Decoded,
        fx: &mut Effects,
        lanes: Option<&mut PioLanes>,
    ) -> Flow {
        let Decoded {
            ins,
            arg1,
            arg2,
            pins_in,
            in_base,
            ..
        } = *d;
        let pins_in_lanes = |l: &PioLanes| lanes::rotr(&l.seen, in_base);
        let s = &self.sm[n];
        let src = match arg2 & 7 {
            0 => pins_in,
            1 => s.x,
            2 => s.y,
            3 => 0,
            5 => {
                // STATUS: all ones when the chosen FIFO level is below STATUS_N.
                let level = bits(s.execctrl, 0, 4) as usize;
                let below = match s.execctrl & (1 << 4) != 0 {
                    false => s.tx.len() < level,
                    true => s.rx.len() < level,
                };
                if below {
                    u32::MAX
                } else {
                    0
                }
            }
            6 => s.isr,
            7 => s.osr,
            _ => 0,
        };
        let v = match bits(ins, 3, 2) {
            1 => !src,
            2 => src.reverse_bits(),
            _ => src,
        };
        if let Some(l) = lanes {
            let pins = pins_in_lanes(l);
            let sl = &mut l.sm[n];
            let src = match arg2 & 7 {
                0 => pins,
                1 => sl.x,
                2 => sl.y,
                6 => sl.isr,
                7 => sl.osr,
                _ => CONST,
            };
            let mut w = match bits(ins, 3, 2) {
                1 => lanes::not(&src),
                2 => lanes::reverse(&src),
                _ => src,
            };
            let p = s.pinctrl;
            match arg1 {
                0 => l.pend[n] = map_lanes(bits(p, 0, 5), bits(p, 20, 6), &w),
                1 => sl.x = w,
                2 => sl.y = w,
                4 => lanes::fix(&mut w, v, 0xffff, &mut l.fixed),
                5 => lanes::fix(&mut w, v, 31, &mut l.fixed),
                6 => sl.isr = w,
                7 => sl.osr = w,
                _ => {}
            }
        }
        let s = &mut self.sm[n];
        match arg1 {
            0..=2 => s.write_pins_x_y(arg1, v, fx),
            4 => {
                s.exec = Some(v as u16);
                s.advance();
                Flow::Stay
            }
            5 => Flow::Jump(v),
            6 => {
                s.isr = v;
                s.isr_count = 0;
                Flow::Next
            }
            7 => {
                s.osr = v;
                s.osr_count = 0;
                Flow::Next
            }
            _ => Flow::Next,
        }
    }

    /// IRQ (3.4.9): set or clear an IRQ flag, maybe waiting for it to clear.
    #[inline(always)]
    fn irq(&mut self, n: usize, d: &Decoded, _lanes: Option<&mut PioLanes>) -> Flow {
        let Decoded { ins, arg2, .. } = *d;
        let irq_index = |idx: u32| d.irq_index(idx);
        let f = irq_index(arg2);
        let clear = ins & 0x40 != 0;
        let wait = ins & 0x20 != 0;
        let s = &mut self.sm[n];
        if clear {
            self.irq &= !(1 << f);
            Flow::Next
        } else if s.irq_waiting {
            // Set on an earlier cycle of this instruction: wait for it to clear.
            match self.irq & (1 << f) != 0 {
                true => Flow::Stall,
                false => {
                    s.irq_waiting = false;
                    Flow::Next
                }
            }
        } else {
            self.irq |= 1 << f;
            match wait {
                true => {
                    s.irq_waiting = true;
                    Flow::Stall
                }
                false => Flow::Next,
            }
        }
    }

    /// SET (3.4.10): an immediate into pins, X, Y or PINDIRS.
    #[inline(always)]
    fn set(
        &mut self,
        n: usize,
        d: &Decoded,
        fx: &mut Effects,
        lanes: Option<&mut PioLanes>,
    ) -> Flow {
        let Decoded { arg1, arg2, .. } = *d;
        let s = &mut self.sm[n];
        if let Some(l) = lanes {
            match arg1 {
                1 => l.sm[n].x = CONST,
                2 => l.sm[n].y = CONST,
                _ => {}
            }
        }
        let (set_base, set_count) = (bits(s.pinctrl, 5, 5), bits(s.pinctrl, 26, 3));
        match arg1 {
            0 => fx.values = StateMachine::map(set_base, set_count, arg2),
            1 => s.x = arg2,
            2 => s.y = arg2,
            4 => fx.dirs = StateMachine::map(set_base, set_count, arg2),
            _ => {}
        }
        Flow::Next
    }
}

/// An instruction's fields and what the pins show the state machine that runs it
/// ([`Pio::run`]).
#[derive(Clone, Copy)]
pub(super) struct Decoded {
    /// The instruction.
    ins: u32,
    /// Bits 7:5 (a condition, source or destination).
    arg1: u32,
    /// Bits 4:0 (an address, bit count, index or immediate).
    arg2: u32,
    /// The GPIO levels the state machines see this cycle.
    gpio: u32,
    /// Those levels rotated to the state machine's IN_BASE.
    pins_in: u32,
    /// PINCTRL's IN_BASE.
    in_base: u32,
    /// The state machine's number.
    sm: u32,
}

impl Decoded {
    /// The IRQ flag an `IRQ` or `WAIT IRQ` index names: with bit 4 (REL), the state
    /// machine's number added to the low two bits (datasheet 3.4.9.2).
    #[inline(always)]
    fn irq_index(&self, idx: u32) -> u32 {
        if idx & 0x10 != 0 {
            (idx & 4) | ((idx + self.sm) & 3)
        } else {
            idx & 7
        }
    }
}

/// What an executed instruction does to PC.
#[derive(Clone, Copy, Debug)]
pub(super) enum Flow {
    /// It stalled: it runs again next time, PC unchanged, no delay.
    Stall,
    /// PC advances through the wrap.
    Next,
    /// PC is set.
    Jump(u32),
    /// PC was already handled (OUT/MOV EXEC: the next cycle runs the executee).
    Stay,
}
