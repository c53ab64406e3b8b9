//! What a built [`FirmwareImage`] tells the host: its loadable segments, the addresses of
//! its cores' pieces and keys, each key's window words and converter channels, its static
//! bounds and tick, and a run of it on the emulated board ([`ImageRun`]).

use super::error::ImageError;
use super::keys::KeySpec;
use super::program::Program;
use super::run::ImageRun;
use super::{glue, io, FirmwareImage, IsrWcet};
use tactus_runtime::limiter::LimiterConfig;

impl FirmwareImage {
    /// The image's loadable bytes: (address, bytes) per piece — the entry stub at
    /// [`boot::ENTRY`], then per core its code block and its data — at their run
    /// addresses (each core's in its bank through the non-striped alias).
    ///
    /// [`boot::ENTRY`]: super::boot::ENTRY
    pub fn segments(&self) -> &[(u32, Vec<u8>)] {
        &self.segments
    }

    /// The turns of core `core`'s sensor checks ([`glue::Turns`]: which samples check
    /// which keys; one class, every sample, on a core without keys taking turns).
    pub fn check_turns(&self, core: usize) -> Option<&glue::Turns> {
        self.turns.get(core)
    }

    /// The watchdog's feed as core 0's handler runs it ([`glue::Feed`]; `None` on an image
    /// without the watchdog): [`glue::Feed::class`] the class of core 0's samples
    /// ([`FirmwareImage::check_turns`]) whose handler feeds, `None` every sample.
    pub fn watchdog_feed(&self) -> Option<&glue::Feed> {
        self.feed.as_ref()
    }

    /// The most samples from one feed of the watchdog to the next on a healthy board: the
    /// feeding class's longest gap ([`glue::Turns::gaps`]), 1 when every sample feeds;
    /// `None` without the watchdog. A hang resets the board more than the watchdog's
    /// period less this many samples, and at most the period and one sample, after the
    /// hang's tick (`super::fault`, "The watchdog").
    pub fn feed_gap(&self) -> Option<u32> {
        let f = self.feed.as_ref()?;
        Some(f.class.map_or(1, |c| {
            self.turns
                .first()
                .and_then(|t| t.gaps.get(usize::from(c)))
                .map_or(1, |g| g.0)
        }))
    }

    /// Samples by which every checked key has had its first check (whose first reading
    /// sets its force to 0 for that sample, [`glue::SensorCheck::seed`]): the longest gap
    /// of any core's turns.
    pub fn first_checks(&self) -> u64 {
        let worst = self.turns.iter().map(glue::Turns::worst_gap).max();
        u64::from(worst.unwrap_or(1))
    }

    /// Per core: (vector table, reset handler, sample interrupt, control block, stack
    /// top), addresses.
    pub fn core_addresses(&self, core: usize) -> Option<[u32; 5]> {
        self.cores
            .get(core)
            .map(|c| [c.vtor, c.reset, c.isr, c.ctrl, c.stack_top])
    }

    /// Core `core`'s return slot: the stack word where an update pushes its return address
    /// into its call site, which the reset handler reads after a watchdog reset to name the
    /// key that hung (`super::fault`, "Which key hung"); `None` for a core beyond the
    /// image's.
    pub fn return_slot(&self, core: usize) -> Option<u32> {
        (self.cores.get(core)).map(|c| super::fault::return_slot(c.stack_top))
    }

    /// Per key (in key-list order): the addresses of its update's call sites in its core's
    /// sample interrupt, one `BL` in each copy of the core's keys code ([`glue::Turns`]),
    /// in copy order (`keys.json`'s `update_calls`); what a hang of that key patches
    /// ([`super::FaultKind::Hang`]), and what the reset handler's table of call sites
    /// names the key by (`super::fault`, "Which key hung").
    pub fn update_calls(&self, key: usize) -> Option<&[u32]> {
        self.keys.get(key).map(|k| &k.calls[..])
    }

    /// Per key (in key-list order): the address of its record (the update's sensor words
    /// first, then its out words, limiter budgets and state address) and of its state.
    pub fn key_addresses(&self, key: usize) -> Option<(u32, u32)> {
        let k = self.keys.get(key)?;
        let at = k.record + k.state_offset;
        let (base, data) = self
            .segments
            .iter()
            .find(|(b, d)| at >= *b && at + 4 <= b + d.len() as u32)?;
        let o = (at - base) as usize;
        let state = u32::from_le_bytes(data.get(o..o + 4)?.try_into().ok()?);
        Some((k.record, state))
    }

    /// Key `key`'s window words (in key-list order): its sensor words (indices from
    /// [`SENSOR_BASE`], in sensor order) and its DAC words (indices from
    /// [`DAC_BASE`], one per force word it drives); `None` for an unknown
    /// key. Each core's keys have the words of the core's own banks (module documentation,
    /// "Split windows").
    ///
    /// [`SENSOR_BASE`]: crate::windows::SENSOR_BASE
    /// [`DAC_BASE`]: crate::windows::DAC_BASE
    pub fn window_words(&self, key: usize) -> Option<(&[usize], &[usize])> {
        self.keys
            .get(key)
            .map(|k| (&k.sensor_words[..], &k.dac_words[..]))
    }

    /// The SRAM banks each core's code, data, stack and window words lie in (bit per
    /// bank: 0-3 SRAM0-3, 4 SRAM4, 5 SRAM5): disjoint, so the emulator may run the cores
    /// as independent machines (`tactus_emulator::Config::own_banks`).
    pub fn own_banks(&self) -> [u8; 2] {
        let mut banks = [0u8; 2];
        for (c, own) in banks.iter_mut().enumerate().take(self.cores.len()) {
            let stack = 4 + c as u8;
            *own = 1 << c | 1 << stack;
            if self.io.is_some() {
                *own |= 1 << (2 + c);
            }
            for &i in &self.cores[c].keys {
                for &w in self.keys[i]
                    .sensor_words
                    .iter()
                    .chain(&self.keys[i].dac_words)
                {
                    *own |= 1 << (w % 4);
                }
            }
        }
        banks
    }

    /// The converters' drivers (`None` for a board without converters: the host fills the
    /// sensor words and reads the DAC words).
    pub fn io(&self) -> Option<&io::IoPlan> {
        self.io.as_ref()
    }

    /// Key `key`'s converter channels (in key-list order): its ADC channels (one per sensor
    /// word) and DAC channels (one per force word) on its core's parts; `None` for an
    /// unknown key, empty without converters.
    pub fn channels(&self, key: usize) -> Option<(&[u32], &[u32])> {
        self.keys
            .get(key)
            .map(|k| (&k.adc_channels[..], &k.dac_channels[..]))
    }

    /// The static latency of key `key` (in key-list order) on a board with converters:
    /// the most core clock cycles from its position's sample to the DAC output that
    /// answers it ([`io::IoPlan::latency_cycles`] of its first ADC and DAC channels);
    /// `None` without converters or for an unknown key.
    pub fn latency_cycles(&self, key: usize) -> Option<u64> {
        let plan = self.io.as_ref()?;
        let k = self.keys.get(key)?;
        Some(plan.latency_cycles(
            k.spec.core,
            *k.adc_channels.first()?,
            *k.dac_channels.first()?,
            &self.tick,
        ))
    }

    /// Static WCET of core `core`'s sample interrupt (`None` for a core beyond the board's).
    pub fn wcet(&self, core: usize) -> Option<IsrWcet> {
        self.wcet.get(core).copied()
    }

    /// Address of the update function key `key` calls (its core's copy of its program), to
    /// profile it on the board (`None` for an unknown key).
    pub fn update_addr(&self, key: usize) -> Option<u32> {
        self.keys.get(key).map(|k| k.update)
    }

    /// Cores of the image.
    pub fn cores(&self) -> usize {
        self.cores.len()
    }

    /// The keys on core `core`, as indices into the key list.
    pub fn core_keys(&self, core: usize) -> &[usize] {
        self.cores.get(core).map_or(&[], |c| &c.keys)
    }

    /// Copies of program code in core `core`'s bank: one per distinct code its keys run
    /// (keys of one instrument with graded params share one, [`Program::same_code`]).
    pub fn code_copies(&self, core: usize) -> usize {
        self.cores.get(core).map_or(0, |c| c.code_copies)
    }

    /// Bytes of code (vector table, program copies, glue) in core `core`'s bank.
    pub fn code_bytes(&self, core: usize) -> u32 {
        self.code_bytes.get(core).copied().unwrap_or(0)
    }

    /// Timer time (µs after the timer's release) of the start alarm, at which both cores
    /// start their SysTick; the first sample tick follows `⌊clock/fs⌋` cycles after the
    /// start handler's enabling store ([`glue::core_code`]).
    pub fn start_alarm_us(&self) -> u32 {
        self.start_alarm_us
    }

    /// The tick schedule: `⌊clock/fs⌋` cycles per period and the fraction `rem/den` of a
    /// cycle more on average ([`glue::Tick`]).
    pub fn tick(&self) -> glue::Tick {
        self.tick
    }

    /// Core clock cycles per sample: the deadline, the shortest interval between two
    /// ticks ([`tactus_runtime::keyboard::deadline_cycles`]).
    pub fn cycles_per_sample(&self) -> u64 {
        tactus_runtime::keyboard::deadline_cycles(self.clock_hz as f64, self.sample_rate_hz as f64)
    }

    /// The limiter configuration the image was built with (at the board's sample rate):
    /// `Limiter::new` of it computes the reference words.
    pub fn limiter_config(&self) -> &LimiterConfig {
        &self.limiter
    }

    /// The programs, as given to [`FirmwareImage::build`].
    pub fn programs(&self) -> &[Program] {
        &self.programs
    }

    /// Sensor words [`ImageRun::step`] takes per sample: the sum over the keys of their
    /// programs' [`Program::sensor_words`] (the number of keys for a keyboard).
    pub fn sensor_words(&self) -> usize {
        self.keys.iter().map(|k| k.sensors).sum()
    }

    /// The keys, as given to [`FirmwareImage::build`].
    pub fn keys(&self) -> Vec<KeySpec> {
        self.keys.iter().map(|k| k.spec).collect()
    }

    /// Loads the image into a fresh emulated board and runs it up to the first tick
    /// (every core's start-up); see [`ImageRun`].
    pub fn run(&self) -> Result<ImageRun, ImageError> {
        ImageRun::new(self, None)
    }

    /// [`FirmwareImage::run`] with the keys where `sensors` (the first sample's words, as
    /// [`ImageRun::step`] takes them) puts them from power-on: on a converter board the
    /// ADC's inputs hold their codes before the boot, so the start handler's burst (the
    /// keys' first reading) samples them, as a real board's samples its keys where they
    /// are; [`FirmwareImage::run`]'s ADC reads its power-on code 0 there (the key at rest),
    /// and a key held elsewhere jumps at the first step. The same as
    /// [`FirmwareImage::run`] on a board without converters, whose first reading is the
    /// first step's.
    ///
    /// Errors: [`ImageError::SensorCount`]; those of [`FirmwareImage::run`].
    pub fn run_at(&self, sensors: &[i32]) -> Result<ImageRun, ImageError> {
        ImageRun::new(self, Some(sensors))
    }
}
