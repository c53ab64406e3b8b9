//! The progress bars of the long commands: a stage bar (`tactus budget`, `tactus build`)
//! and the play loop's bar (`tactus play`: key-samples on a host engine; music time,
//! real-time factor and ETA on the emulated boards).

use indicatif::{MultiProgress, ProgressBar, ProgressState, ProgressStyle};
use std::fmt::Write;

/// A bar for a library's `progress(stage, done, total)` callback: the stage's name, then
/// `done/total`.
pub struct StageBar(ProgressBar);

impl StageBar {
    /// A new bar on stderr.
    pub fn new() -> StageBar {
        let bar = ProgressBar::new(1);
        bar.set_style(
            ProgressStyle::with_template("{msg:>16} [{bar:30}] {pos}/{len}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        StageBar(bar)
    }

    /// Shows `done` of `total` in `stage`.
    pub fn update(&self, stage: &str, done: usize, total: usize) {
        self.0.set_message(stage.to_string());
        self.0.set_length(total as u64);
        self.0.set_position(done as u64);
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

/// The play loop's bar ([`tactus_host::play::Progress`]).
pub struct PlayBar(pub ProgressBar);

impl PlayBar {
    /// A new bar showing `msg`, on stderr or below the corpus bar of `multi`.
    pub fn new(multi: Option<&MultiProgress>, msg: String) -> PlayBar {
        let bar = match multi {
            Some(m) => m.add(ProgressBar::new(0)),
            None => ProgressBar::new(0),
        };
        bar.set_message(msg);
        PlayBar(bar)
    }
}

/// Corpus mode's bar over the pieces, with each piece's [`PlayBar`] below it.
pub struct CorpusBar {
    /// The bars, so that messages printed while they run do not tear them.
    pub multi: MultiProgress,
    outer: ProgressBar,
}

impl CorpusBar {
    /// A bar over `pieces` pieces.
    pub fn new(pieces: usize) -> CorpusBar {
        let multi = MultiProgress::new();
        let outer = multi.add(ProgressBar::new(pieces as u64));
        outer.set_style(
            ProgressStyle::with_template(
                "{msg} [{bar:30}] {pos}/{len} pieces, elapsed {elapsed}, eta {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        CorpusBar { multi, outer }
    }

    /// Shows the piece being played.
    pub fn piece(&self, file: &std::path::Path) {
        self.outer
            .set_message(format!("corpus: {}", file.display()));
    }

    /// Counts a piece done.
    pub fn inc(&self) {
        self.outer.inc(1);
    }

    /// Removes the bars.
    pub fn finish(&self) {
        self.outer.finish_and_clear();
    }
}

impl tactus_host::play::Progress for PlayBar {
    fn start(&self, total: u64, per_second: Option<f64>) {
        self.0.set_length(total);
        self.0.set_style(match per_second {
            Some(k) => music_style(k),
            None => ProgressStyle::with_template(
                "{spinner} {msg} [{bar:30}] {percent}% {per_sec} key-samples, eta {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        });
    }
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
}

/// The style of the bar on the emulated boards, whose position counts key-samples
/// (`key_samples_per_s` per second of music): music time done and in all, the real-time
/// factor so far and the time left.
fn music_style(key_samples_per_s: f64) -> ProgressStyle {
    let k = key_samples_per_s.max(1.0);
    ProgressStyle::with_template(
        "{spinner} {msg} [{bar:30}] {music} of music, real-time factor {rtf}, eta {eta}",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar())
    .with_key("music", move |s: &ProgressState, w: &mut dyn Write| {
        let total = s.len().map_or(0.0, |l| l as f64 / k);
        let _ = write!(w, "{:.1} s / {total:.1} s", s.pos() as f64 / k);
    })
    .with_key("rtf", move |s: &ProgressState, w: &mut dyn Write| {
        let secs = s.elapsed().as_secs_f64();
        let _ = match secs > 0.0 {
            true => write!(w, "{:.2}", s.pos() as f64 / k / secs),
            false => write!(w, "–"),
        };
    })
}
