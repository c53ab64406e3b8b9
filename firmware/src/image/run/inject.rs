//! Faults injected into a running board ([`ImageRun::inject`]), and the board's resets.
//!
//! **Through the inputs the emulator keys on.** Every fault enters the board the way its
//! inputs already do, so that the block engine's memos, the I/O's period memo and the rest
//! replay stay exact: a sensor fault changes the key's sensor word (a board without
//! converters) or the code its ADC channel reads (`Board::set_adc_code`, with them); a
//! flipped bit and a hung update are host writes to SRAM between samples (`write_data`,
//! `write_bytes`, which drops decoded code: a hang calls a loop, [`HANG_STUB`], from the
//! key's calls of its update, `KeyPlace::calls`, so that the key alone hangs); the ADC's silence, the DAC's stall and a
//! brown-out change the emulated parts or chip between samples. A recording of the rest
//! replay never spans a change: the replay is left and forgotten at each.
//!
//! **Sensor faults** are defined on the key's ADC code, the 16-bit code of its sensor's
//! declared range ([`AdcScale::new`] over `sensor_raw_range`, the scale a converter board
//! reads it with): open reads code 0, short full scale (65,535), stuck a code, a jump the
//! code plus a step, noise the code plus a pseudo-random value in ±amplitude each sample.
//! Without converters the key's sensor word is the word of that code, `lo + code << shift`
//! (not clamped to the range: a short reads beyond it, as the ADC's full scale lies beyond
//! the key's travel).
//!
//! **Resets.** When the watchdog resets the board (`tactus_emulator::watchdog`) the run
//! follows the firmware's boot to its first sample tick ([`super::run_to_first_tick`]) and
//! gives zero-force samples for the samples that took (the DACs are cleared at the reset,
//! `tactus_emulator::converters::Dac8568`'s CLR; without converters the host reads zero
//! from the reset until the firmware's handler runs again); the board's clock then runs
//! behind the host's by less than a sample. A RAM image boots again through the boot ROM's
//! watchdog entry (`super::super::reboot`), a flash image from flash. A board that cannot
//! boot again (a brown-out of a RAM image, or a RAM image without a re-entry: USB boot)
//! gives zero forces from then on and says why ([`ImageRun::resets`]). A fault that starts
//! or ends in the samples of zero force while a board boots again takes effect at the
//! first sample of the new boot, before its firmware runs it (a hang that clears there
//! lets the new boot play).
//!
//! **Late samples.** With faults injected and the board's watchdog counting, a core that
//! has not finished a sample by the next tick (a hung update) does not hold the host's
//! clock: the sample is given as the board stands at that tick ([`ImageRun::late_sample`]:
//! the late core's drives hold what they last were, as its DAC does, its handler counted
//! as none finished, the other core playing on), and so is each sample after it until the
//! core catches up or the watchdog resets the board. So every sample the host gives is
//! one period of the board's clock, and a reset falls in the host's sample when it
//! happened: a hung core's motors hold their force for the watchdog's period, then are at
//! zero. (Without the watchdog nothing ends a hang: the run waits for the core, as for an
//! overloaded image, and gives up with an error.)

use super::*;
use tactus_isa::decode::Instr;
use tactus_runtime::converters::AdcScale;

/// The code a hung key's calls enter ([`FaultKind::Hang`]): `PUSH {LR}; B .`, a loop entered
/// as an update is, its return address pushed where an update's prologue pushes it (the
/// core's return slot, `super::super::fault`, "Which key hung").
pub const HANG_STUB: [Instr; 2] = [Instr::Push { list: 1 << 14 }, Instr::B { offset: -4 }];

/// What a fault does ([`Injection`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultKind {
    /// The key's sensor reads code 0 (a broken wire).
    Open,
    /// The key's sensor reads full scale, 65,535 (a short to the reference).
    Short,
    /// The key's sensor reads this code.
    Stuck(u16),
    /// The key's sensor reads its code plus this step (saturated to 0–65,535).
    Jump(i32),
    /// The key's sensor reads its code plus a pseudo-random value in ±this, each sample.
    Noise(u16),
    /// The ADC of this core answers all ones on every channel (its SDO stuck high); without
    /// converters every sensor word of the core's keys reads full scale.
    AdcSilent,
    /// The ADC of this core raises no more DREQ (a converter board's: its state machine,
    /// which clocks the ADC and fills the RX FIFO whose DREQ paces the results channel,
    /// stops: `CTRL.SM_ENABLE` of the ADC's state machine cleared, set again when it
    /// clears): the DMA channel that reads the results never completes its burst, and the
    /// commands channel stops when the TX FIFO is full. A board without converters has no
    /// ADC: an error.
    AdcNoDreq,
    /// The DAC of this core takes no more frames (its SPI link broken): its outputs hold
    /// their codes, so the codes the host reads for the core's drives hold those of the
    /// sample before (with or without converters). Nothing on the RP2040 sees it: the
    /// DAC8568 has no read-back.
    DacStall,
    /// The key's update never returns: each of the key's calls of its update in its core's
    /// sample interrupt (one per copy of the core's keys code, `glue::Turns`; the image's
    /// `update_calls`, `keys.json`'s) calls [`HANG_STUB`] instead, so this key alone hangs
    /// its core, at its next update (a key the quiescent-key guard skips reaches it when it
    /// moves), with its return address on the stack where a real hang in its update leaves
    /// it.
    Hang,
    /// Bit `bit` (0–31) of word `word` of the key's state struct flips once.
    Flip {
        /// The state word (0-based).
        word: u32,
        /// The bit.
        bit: u8,
    },
    /// The supply dips: a power-on reset (SRAM lost; `Board::brown_out`).
    BrownOut,
}

impl FaultKind {
    /// Whether the fault is on a key's sensor.
    pub fn is_sensor(&self) -> bool {
        matches!(
            self,
            FaultKind::Open
                | FaultKind::Short
                | FaultKind::Stuck(_)
                | FaultKind::Jump(_)
                | FaultKind::Noise(_)
        )
    }
}

/// One fault on a board: what, where (a key of the board, index in its key list, or a
/// core), and the samples it lasts: from sample `from` (counted from the run's first) to
/// before `until` (`None`: to the end; a flip and a brown-out happen once, at `from`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Injection {
    /// The fault.
    pub kind: FaultKind,
    /// The key (sensor faults, hang, flip).
    pub key: Option<usize>,
    /// The core (the ADC's and the DAC's faults).
    pub core: Option<usize>,
    /// The first sample it is in.
    pub from: u64,
    /// The first sample it is over, if it clears.
    pub until: Option<u64>,
}

impl Injection {
    fn active(&self, n: u64) -> bool {
        n >= self.from && self.until.is_none_or(|u| n < u)
    }

    fn one_shot(&self) -> bool {
        matches!(self.kind, FaultKind::Flip { .. } | FaultKind::BrownOut)
    }
}

/// A reset the run met: the sample, the board's cycle, why, and whether the firmware ran
/// again (or why not).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResetRecord {
    /// The sample during which the board reset.
    pub sample: u64,
    /// The board's cycle of the reset.
    pub cycle: u64,
    /// `watchdog timer`, `watchdog trigger` or `brown-out`.
    pub why: &'static str,
    /// Samples of zero force while the firmware booted, after the reset's own sample (which
    /// the run gives at zero force too: `reboot + 1` in all, the next sample the new boot's
    /// first); `Err` when it did not boot again.
    pub reboot: Result<u64, String>,
}

impl ResetRecord {
    /// Whether the watchdog reset the board (its timer or a trigger), not a brown-out.
    pub fn by_watchdog(&self) -> bool {
        self.why.starts_with("watchdog")
    }

    /// Whether the watchdog's CTRL.TRIGGER reset the board (the firmware's HardFault
    /// handler's reset at once: `glue::checks::hard_fault_handler`), not its timer.
    pub fn by_trigger(&self) -> bool {
        self.why == "watchdog trigger"
    }

    /// Whether a brown-out reset the board (a power-on reset: SRAM lost).
    pub fn by_brown_out(&self) -> bool {
        self.why == "brown-out"
    }
}

/// The faults of a run and what they left (module documentation).
#[derive(Debug, Default)]
pub(super) struct Faults {
    list: Vec<Injection>,
    /// Per flat sensor word, its scale (made when the first sensor fault is injected).
    scales: Vec<AdcScale>,
    /// The effective sensor words of the sample under way.
    pub(super) buf: Vec<i32>,
    /// Per flat sensor word, the ADC code forced this sample (converter boards).
    pub(super) codes: Vec<Option<u16>>,
    /// The codes forced last sample: a change leaves the rest replay.
    last_codes: Vec<Option<u16>>,
    /// A hung key's call sites: the key, the address and the `BL` it replaced.
    hung: Vec<(usize, u32, [u8; 4])>,
    /// Per drive of every key (flat, key order): the DAC code it holds while its core's
    /// DAC is stalled.
    pub(super) frozen: Vec<Option<i32>>,
    /// The first of the late samples under way ("Late samples"), if the last was late.
    pub(super) late_since: Option<u64>,
    /// Per core, the samples it had not finished by the next tick ([`ImageRun::unfinished`]).
    unfinished: [u64; 2],
    /// A brown-out was injected this sample.
    browned: bool,
    /// The board's cycle at the last brown-out.
    brown_at: u64,
    /// The watchdog resets seen.
    resets_seen: u64,
    /// Resets and brown-outs met.
    pub(super) resets: Vec<ResetRecord>,
    /// Zero-force samples left while the firmware boots again.
    pub(super) zero_left: u64,
    /// The board cannot run again (why).
    pub(super) dead: Option<String>,
    /// The sample tick `first_tick` is tick 0 of, and the firmware's sample count then.
    pub(super) tick_base: u64,
    pub(super) count_base: u32,
    /// xorshift32 state of the noise.
    seed: u32,
    /// The first sample whose starts and ends are not yet done to the board.
    next_applied: u64,
}

fn noise(seed: &mut u32, amplitude: u16) -> i32 {
    let mut x = *seed;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *seed = x;
    let span = 2 * u32::from(amplitude) + 1;
    (x % span) as i32 - i32::from(amplitude)
}

/// The noise's first xorshift32 state ([`FaultKind::sensor_code`]).
pub const NOISE_SEED: u32 = 0x2545_f491;

impl FaultKind {
    /// The ADC code a key's sensor reads under this fault when it would read `code`
    /// (module documentation): 0 open, 65,535 short or a silent ADC, the stuck code, the
    /// code plus the jump, or plus a noise value drawn from `seed` (xorshift32, from
    /// [`NOISE_SEED`]), saturated to 0–65,535; `code` itself for a fault not on a sensor.
    pub fn sensor_code(self, code: u16, seed: &mut u32) -> u16 {
        let code = i64::from(code);
        match self {
            FaultKind::Open => 0,
            FaultKind::Short | FaultKind::AdcSilent => 0xffff,
            FaultKind::Stuck(c) => i64::from(c),
            FaultKind::Jump(d) => code + i64::from(d),
            FaultKind::Noise(a) => code + i64::from(noise(seed, a)),
            _ => code,
        }
        .clamp(0, 0xffff) as u16
    }
}

/// The sensor word of ADC code `code` on a board without converters: `lo + code <<
/// shift`, not clamped to the range (a short reads beyond it), saturated to an `i32`.
pub fn code_word(scale: &AdcScale, code: u16) -> i32 {
    let word = i64::from(scale.lo) + (i64::from(code) << scale.shift);
    word.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

impl ImageRun {
    /// Adds a fault (module documentation).
    ///
    /// Errors, as text naming the field: a key or core the board does not have, a fault
    /// that needs a key or a core without one, a flip outside the key's state struct or
    /// beyond bit 31, an end not after the start.
    pub fn inject(&mut self, f: Injection) -> Result<(), String> {
        let keys = self.image.keys.len();
        let needs_key =
            f.kind.is_sensor() || matches!(f.kind, FaultKind::Hang | FaultKind::Flip { .. });
        match (needs_key, f.key) {
            (true, None) => return Err("`key`: this fault needs a key".into()),
            (_, Some(k)) if k >= keys => {
                return Err(format!("`key`: key {k} on a board of {keys} keys"))
            }
            _ => {}
        }
        if f.kind == FaultKind::AdcNoDreq && self.image.io.is_none() {
            return Err(
                "`kind`: `adc-no-dreq` stops the ADC's state machine of a converter \
                        board (`rp2040_io`): this board has no converters (no `[converters]` \
                        in its board file), so no ADC and no DREQ"
                    .into(),
            );
        }
        if matches!(
            f.kind,
            FaultKind::AdcSilent | FaultKind::AdcNoDreq | FaultKind::DacStall
        ) {
            match f.core {
                None => return Err("`core`: this fault needs a core".into()),
                Some(c) if c >= self.image.cores.len() => {
                    return Err(format!(
                        "`core`: core {c} on a board of {} cores",
                        self.image.cores.len()
                    ))
                }
                _ => {}
            }
        }
        if let (FaultKind::Flip { word, bit }, Some(k)) = (f.kind, f.key) {
            let p = &self.image.programs[self.image.keys[k].spec.program];
            let words = p.thumb.state.size / 4;
            if word as usize >= words {
                return Err(format!(
                    "`word`: word {word} of a state struct of {words} words"
                ));
            }
            if bit > 31 {
                return Err(format!("`bit`: bit {bit} of a 32-bit word"));
            }
        }
        if f.until.is_some_and(|u| u <= f.from) {
            return Err("`until`: the fault must end after it starts".into());
        }
        if self.faults.scales.is_empty() {
            for k in &self.image.keys {
                let p = &self.image.programs[k.spec.program];
                for i in 0..p.sensor_words() {
                    let (lo, hi) = p.fixed.sensor_raw_range.get(i).copied().unwrap_or((0, 0));
                    self.faults.scales.push(AdcScale::new(lo, hi, 16));
                }
            }
            let drives = self.image.keys.iter().map(|k| k.drives.len()).sum();
            self.faults.frozen = vec![None; drives];
            self.faults.seed = NOISE_SEED;
        }
        self.faults.list.push(f);
        // The board answers a fault exception as the chip does: its firmware's HardFault
        // handler runs (with the watchdog, it records the fault and resets the board at
        // once: `glue::checks::hard_fault_handler`), and the reset is followed as any
        // ("Resets"). Without injected faults the run stops at the fault instead, naming
        // the core, the instruction and why (`Config::stop_on_fault`): there a HardFault is
        // the firmware's bug, never an answer to be tested. Without the watchdog the handler
        // is `B .`: the run stops at the fault too, which says more than the hang would.
        self.board.config.stop_on_fault = !self.image.programs.iter().any(|p| p.watchdog);
        Ok(())
    }

    /// Where a hang of a key of core `core` loops ([`FaultKind::Hang`]): the word after
    /// the core's code block, written with [`HANG_STUB`] (again at each hang: a flash
    /// boot may have copied a piece over it), in the core's own bank.
    ///
    /// Errors: [`ImageError::Run`] when an image segment lies there.
    fn hang_stub(&mut self, core: usize) -> Result<u32, ImageError> {
        let vtor = self.image.cores[core].vtor;
        let segs = &self.image.segments;
        let end = (segs.iter())
            .find(|(at, d)| (*at..*at + d.len() as u32).contains(&vtor))
            .map(|(at, d)| at + d.len() as u32)
            .ok_or_else(|| ImageError::Run(format!("core {core}: no code block at its VTOR")))?;
        let stub = end.next_multiple_of(4);
        let taken = |(at, d): &(u32, Vec<u8>)| stub < at + d.len() as u32 && *at < stub + 4;
        if segs.iter().any(taken) {
            return Err(ImageError::Run(format!(
                "core {core}: no free word after its code block at {stub:#010x} for the hang"
            )));
        }
        let mut code = Vec::with_capacity(4);
        for i in &HANG_STUB {
            let e = tactus_isa::encode::encode(i)
                .map_err(|e| ImageError::Run(format!("the hang's loop: {e}")))?;
            code.extend(e.bytes());
        }
        self.board.write_bytes(stub, &code).map_err(emu)?;
        Ok(stub)
    }

    /// Whether any fault was injected.
    pub(super) fn has_faults(&self) -> bool {
        !self.faults.list.is_empty()
    }

    /// The resets met so far (module documentation).
    pub fn resets(&self) -> &[ResetRecord] {
        &self.faults.resets
    }

    /// Per core (as many as the image has), the samples it had not finished by the next
    /// tick ("Late samples": a hung handler, which never returns; the watchdog's reset
    /// cuts it). Such a handler is no handler run: its cycles are in no
    /// [`SampleOut::core_cycles`] (that of a sample cut by a reset holds the runs that
    /// completed before it).
    pub fn unfinished(&self) -> &[u64] {
        &self.faults.unfinished[..self.image.cores.len().min(2)]
    }

    /// The samples from `n` on in which nothing injected changes (`give_while`'s bound):
    /// 0 while a fault that varies each sample is active.
    pub(super) fn faults_quiet(&self, n: u64) -> u64 {
        if self.faults.zero_left > 0 || self.faults.dead.is_some() {
            return 0;
        }
        let mut quiet = u64::MAX;
        for f in &self.faults.list {
            if f.active(n) && matches!(f.kind, FaultKind::Noise(_)) {
                return 0;
            }
            for at in [Some(f.from), f.until].into_iter().flatten() {
                if at >= n {
                    quiet = quiet.min(at - n);
                }
            }
        }
        quiet
    }

    /// The sensor words of sample `self.samples` with the sensor faults applied, into
    /// `faults.buf` and `faults.codes`; the faults that start or end at this sample done to
    /// the board. Returns whether the rest replay must be left (an input changed otherwise
    /// than through the words).
    pub(super) fn apply_faults(&mut self, sensors: &[i32]) -> Result<bool, ImageError> {
        let n = self.samples;
        let io = self.image.io.is_some();
        let mut buf = std::mem::take(&mut self.faults.buf);
        buf.clear();
        buf.extend_from_slice(sensors);
        let words = buf.len();
        let mut codes = std::mem::take(&mut self.faults.codes);
        codes.clear();
        codes.resize(words, None);
        let mut changed = false;
        // Flat sensor word ranges per key and per core.
        let mut first = Vec::with_capacity(self.image.keys.len());
        let mut at = 0;
        for k in &self.image.keys {
            first.push(at);
            at += self.image.programs[k.spec.program].sensor_words();
        }
        let list = self.faults.list.clone();
        // A start or an end in the samples since the last applied (those of zero force
        // while the board booted again) takes effect now, before the firmware's next sample.
        let since = self.faults.next_applied..=n;
        self.faults.next_applied = n + 1;
        for f in &list {
            let starts = since.contains(&f.from);
            let ends = f.until.is_some_and(|u| since.contains(&u));
            if starts || ends {
                changed = true;
            }
            match f.kind {
                FaultKind::Flip { word, bit } if starts => {
                    let k = &self.image.keys[f.key.unwrap_or(0)];
                    let board = &mut self.board;
                    let state = board.read_u32(k.record + k.state_offset).map_err(emu)?;
                    let a = state.wrapping_add(4 * word);
                    let v = board.read_u32(a).map_err(emu)? ^ (1 << bit);
                    board.write_data(a, &v.to_le_bytes()).map_err(emu)?;
                }
                FaultKind::BrownOut if starts => {
                    self.board.brown_out();
                    self.faults.browned = true;
                    self.faults.brown_at = self.board.cycle();
                }
                FaultKind::Hang if starts && !ends => {
                    // Each of the key's calls of its update (one per copy of its core's
                    // keys code) a call of the hang stub instead: that key alone enters a
                    // loop that never returns, its return address pushed where its update
                    // pushes it; the keys sharing its code call the update as before.
                    let k = f.key.unwrap_or(0);
                    let stub = self.hang_stub(self.image.keys[k].spec.core)?;
                    for &a in &self.image.keys[k].calls {
                        let mut old = [0u8; 4];
                        self.board.read_bytes(a, &mut old).map_err(emu)?;
                        let offset = stub.wrapping_sub(a + 4) as i32;
                        let bl = tactus_isa::encode::encode(&Instr::Bl { offset })
                            .map_err(|e| ImageError::Run(format!("the hang's call: {e}")))?;
                        self.board.write_bytes(a, &bl.bytes()).map_err(emu)?;
                        self.faults.hung.push((k, a, old));
                    }
                }
                FaultKind::Hang if ends => {
                    let k = f.key.unwrap_or(0);
                    let (back, kept) = std::mem::take(&mut self.faults.hung)
                        .into_iter()
                        .partition(|h| h.0 == k);
                    self.faults.hung = kept;
                    for (_, a, old) in back {
                        self.board.write_bytes(a, &old).map_err(emu)?;
                    }
                }
                FaultKind::AdcNoDreq if starts != ends => {
                    // The ADC's state machine (SM 0 of the core's PIO block, `super::super::io`)
                    // stops, or runs again: CTRL's SM_ENABLE bit through the CLR or SET alias.
                    let c = f.core.unwrap_or(0);
                    let alias = if starts {
                        tactus_rp2040::ATOMIC_CLR
                    } else {
                        tactus_rp2040::ATOMIC_SET
                    };
                    let ctrl = super::super::io::pio_base(c) + tactus_rp2040::pio::reg::CTRL;
                    if !self.board.io_write(ctrl + alias, 1) {
                        return Err(ImageError::Run(format!(
                            "core {c}: the ADC's state machine cannot be stopped (no PIO block)"
                        )));
                    }
                }
                FaultKind::DacStall if starts || ends => {
                    // The DAC holds its outputs: the host reads the codes of the sample
                    // before the stall for the core's drives until it ends.
                    let c = f.core.unwrap_or(0);
                    let mut flat = 0;
                    for (i, k) in self.image.keys.iter().enumerate() {
                        for j in 0..k.drives.len() {
                            if k.spec.core == c {
                                let held = i32::from(self.sample.drives[i][j].dac);
                                if let Some(fz) = self.faults.frozen.get_mut(flat) {
                                    *fz = (starts && !ends).then_some(held);
                                }
                            }
                            flat += 1;
                        }
                    }
                }
                _ => {}
            }
            if !f.active(n) || f.one_shot() {
                continue;
            }
            let targets: Vec<usize> = match (f.kind, f.key, f.core) {
                (FaultKind::AdcSilent, _, Some(c)) => (self.image.keys.iter().enumerate())
                    .filter(|(_, k)| k.spec.core == c)
                    .flat_map(|(i, k)| {
                        first[i]..first[i] + self.image.programs[k.spec.program].sensor_words()
                    })
                    .collect(),
                (kind, Some(k), _) if kind.is_sensor() => {
                    let p = &self.image.programs[self.image.keys[k].spec.program];
                    (first[k]..first[k] + p.sensor_words()).collect()
                }
                _ => Vec::new(),
            };
            for w in targets {
                let Some(scale) = self.faults.scales.get(w).copied() else {
                    continue;
                };
                let code = scale.code(buf[w]).min(0xffff) as u16;
                let faulted = f.kind.sensor_code(code, &mut self.faults.seed);
                if io {
                    codes[w] = Some(faulted);
                } else {
                    buf[w] = code_word(&scale, faulted);
                }
            }
        }
        if codes != self.faults.last_codes {
            changed = true;
            self.faults.last_codes.clone_from(&codes);
        }
        self.faults.codes = codes;
        self.faults.buf = buf;
        Ok(changed)
    }

    /// After the board's run of a sample: whether it reset (the watchdog, or a brown-out
    /// injected this sample); if so, follows its boot (module documentation) and returns
    /// true: the sample is one of zero force.
    pub(super) fn after_reset(&mut self, stop: StopReason) -> Result<bool, ImageError> {
        let brown = std::mem::take(&mut self.faults.browned);
        let (resets, last) = self.board.system.watchdog.resets();
        let by_watchdog = resets != self.faults.resets_seen;
        if !by_watchdog && !brown {
            // No reset (a stop otherwise is the caller's to report).
            let _ = stop;
            return Ok(false);
        }
        self.faults.resets_seen = resets;
        let why = match (brown, last.map(|r| r.reason)) {
            (true, _) => "brown-out",
            (_, Some(tactus_emulator::watchdog::Reason::Force)) => "watchdog trigger",
            _ => "watchdog timer",
        };
        let cycle = match brown {
            true => self.faults.brown_at,
            false => last.map_or(self.board.cycle(), |r| r.cycle),
        };
        let sample = self.samples;
        let start = self.board.cycle();
        let alarm = self.image.start_alarm_us as u64;
        let cores = self.image.cores.len();
        let reboot = run_to_first_tick(&mut self.board, alarm, cores);
        // Core 0 parked: the boot ROM found no entry and no flash image (USB boot).
        let usb = self.board.cores[0].state == tactus_emulator::core::RunState::Parked;
        let reboot = reboot.map_err(|e| match (usb, brown) {
            (false, _) => e,
            (true, true) => "a brown-out clears SRAM, where this RAM image lived, and the \
                             flash holds no image: the boot ROM waits in USB boot (BOOTSEL \
                             mode), nothing of the image runs"
                .into(),
            (true, false) => format!(
                "the boot ROM found no watchdog entry and no image in flash: it waits in USB \
                 boot (BOOTSEL mode), nothing of the image runs (this RAM image has no \
                 re-entry: {})",
                self.image.ram_reboot().err().unwrap_or("?")
            ),
        });
        let reboot = reboot.map(|first| {
            let period = self.image.cycles_per_sample().max(1);
            let zero = (first.saturating_sub(start)).div_ceil(period).max(1);
            self.first_tick = first;
            // The reset's sample and `zero` more at zero force: the next is tick 0.
            self.faults.tick_base = sample + zero + 1;
            let sram = &self.board.system.sram;
            self.faults.count_base = word(sram, self.at.samples[0]);
            zero
        });
        match &reboot {
            Ok(zero) => self.faults.zero_left = *zero,
            Err(e) => self.faults.dead = Some(e.clone()),
        }
        self.stalls = self.board.system.contention_stalls;
        self.faults.late_since = None;
        self.faults.resets.push(ResetRecord {
            sample,
            cycle,
            why,
            reboot,
        });
        Ok(true)
    }

    /// Gives sample `want` (counted from 1) of a core that has not finished it by the next
    /// tick ("Late samples"): the outputs as the board holds them.
    ///
    /// Errors: [`ImageError::Run`] when the core has not finished a sample for as long
    /// as the run waits for an overloaded one (1,000 periods: a watchdog that never
    /// resets the board); those of the sample's collection.
    pub(super) fn late_sample(&mut self, want: u64) -> Result<(), ImageError> {
        let since = *self.faults.late_since.get_or_insert(want);
        if want - since >= u64::from(MAX_EXTRA_EIGHTHS / 8) {
            return Err(ImageError::Run(format!(
                "sample {since} not completed {} periods after its tick",
                MAX_EXTRA_EIGHTHS / 8
            )));
        }
        let (base, count_base) = (self.faults.tick_base, self.faults.count_base);
        let sram = &self.board.system.sram;
        for (c, &o) in self.at.samples.iter().enumerate() {
            if (word(sram, o).wrapping_sub(count_base) as u64) < want - base {
                self.faults.unfinished[c] += 1;
            }
        }
        self.rest.forget();
        self.samples = want;
        self.collect()
    }

    /// A sample of zero force (a board rebooting or dead): every drive's force, current and
    /// DAC code 0, no events, no handler.
    pub(super) fn zero_sample(&mut self) {
        let s = &mut self.sample;
        s.events.clear();
        for d in s.drives.iter_mut().flatten() {
            d.force = 0;
            d.dac = 0;
            d.current_ua = self.limiter.current_ua(0);
        }
        s.force.fill(0);
        s.dac.fill(0);
        let zero = self.limiter.current_ua(0);
        s.current_ua.fill(zero);
        s.core_cycles.fill(0);
        s.handler_runs.fill(0);
    }
}
