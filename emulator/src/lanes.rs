//! Lanes: where each bit of the I/O's data comes from while a window's replay is recorded
//! for the period memo (`board/io_window.rs`, issue 40).
//!
//! A converter board's I/O does the same thing every sample period but for its data: the
//! codes its ADCs sample, the DAC words the handlers leave, the results the DMA writes. The
//! period memo records one replay and gives later ones whose *control* repeats, with their
//! own data. For that the recording run tracks, beside every data word of the machine
//! (the state machines' X, Y, ISR, OSR and FIFO words, the pins' levels and the input
//! synchronisers, the DMA's transfers in flight, the parts' codes, shift and DAC registers),
//! a [`Word`] of lanes: per bit, either a constant (its value in the recorded run, whatever
//! the inputs) or one bit of one *input*, maybe inverted. The inputs are the machine's data
//! words at the window's start (`crate::io::Io::data_slots`) and each SRAM word the DMA
//! reads. Only moves keep a lane: a shift, an `IN`, an `OUT`, a FIFO, a pin, a DMA transfer,
//! a part's shift register. Wherever data decides something — a `JMP` on X, a `WAIT` on a
//! pin, a part decoding its command, a pin's level that may be a clock edge — the lanes it
//! reads are *fixed*: each becomes a constraint (that input bit must have the value it had)
//! and a constant from then on. So a recorded replay stands for every replay from the same
//! control state whose inputs meet its constraints, and gives its data by its routes
//! (`Route`): each output bit a constant or an input bit.
//!
//! Nothing here runs outside a recording: the machine's lanes are `None` then.

/// Where one bit comes from: a constant, or bit `b` of input `i`, maybe inverted
/// (`((i << 5 | b) + 1) << 1 | inverted`; 0 is the constant).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Lane(u32);

impl Lane {
    /// A constant bit.
    pub(crate) const CONST: Lane = Lane(0);

    /// Bit `bit` (0–31) of input `input`.
    pub(crate) fn input(input: u32, bit: u32) -> Lane {
        Lane(((input << 5 | bit) + 1) << 1)
    }

    /// Whether it is a constant.
    pub(crate) fn is_const(self) -> bool {
        self.0 == 0
    }

    /// The bit inverted (a constant stays one).
    pub(crate) fn not(self) -> Lane {
        match self.0 {
            0 => self,
            v => Lane(v ^ 1),
        }
    }

    /// (input, bit, inverted), or `None` for a constant.
    pub(crate) fn source(self) -> Option<(u32, u32, bool)> {
        let v = self.0.checked_sub(2)? >> 1;
        Some((v >> 5, v & 31, self.0 & 1 != 0))
    }
}

/// The lanes of a 32-bit word, bit 0 first.
pub type Word = [Lane; 32];

/// A word of constants.
pub const CONST: Word = [Lane::CONST; 32];

/// The low `bits` bits of input `input`, the rest constant.
pub(crate) fn input_word(input: u32, bits: u32) -> Word {
    let mut w = CONST;
    for (b, l) in w.iter_mut().enumerate().take(bits as usize) {
        *l = Lane::input(input, b as u32);
    }
    w
}

/// `w` shifted left by `n` (constants in), as `v << n`.
pub(crate) fn shl(w: &Word, n: u32) -> Word {
    let mut r = CONST;
    if n < 32 {
        r[n as usize..].copy_from_slice(&w[..32 - n as usize]);
    }
    r
}

/// `w` shifted right by `n` (constants in), as `v >> n`.
pub(crate) fn shr(w: &Word, n: u32) -> Word {
    let mut r = CONST;
    if n < 32 {
        r[..32 - n as usize].copy_from_slice(&w[n as usize..]);
    }
    r
}

/// `w` rotated right by `n`, as `v.rotate_right(n)`.
pub(crate) fn rotr(w: &Word, n: u32) -> Word {
    let mut r = *w;
    r.rotate_left(n as usize % 32);
    r
}

/// `w` rotated left by `n`, as `v.rotate_left(n)`.
pub(crate) fn rotl(w: &Word, n: u32) -> Word {
    let mut r = *w;
    r.rotate_right(n as usize % 32);
    r
}

/// `w` with its bits reversed, as `v.reverse_bits()`.
pub(crate) fn reverse(w: &Word) -> Word {
    let mut r = *w;
    r.reverse();
    r
}

/// `w` inverted, as `!v`.
pub(crate) fn not(w: &Word) -> Word {
    w.map(Lane::not)
}

/// `w` with the bits outside `mask` constant, as `v & mask`.
pub(crate) fn and(w: &Word, mask: u32) -> Word {
    select(mask, w, &CONST)
}

/// `a` where `mask` is set, `b` elsewhere: `v & mask | u & !mask`.
#[inline]
pub(crate) fn select(mask: u32, a: &Word, b: &Word) -> Word {
    match mask {
        0 => *b,
        u32::MAX => *a,
        _ => {
            let mut r = *b;
            let mut m = mask;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                r[i] = a[i];
                m &= m - 1;
            }
            r
        }
    }
}

/// Whether every lane of `w` is a constant.
pub(crate) fn is_const(w: &[Lane]) -> bool {
    w.iter().all(|l| l.is_const())
}

/// A fixed bit: the input bit the lane names had the value its lane's bit had in the
/// recorded run (the module documentation).
pub(crate) type Fixed = (Lane, bool);

/// Fixes the lanes of `w` under `mask` (their bits of `value` decided something, as
/// recorded): a constraint into `into` for each that is not constant, which is constant
/// from then on.
pub(crate) fn fix(w: &mut [Lane], value: u32, mask: u32, into: &mut Vec<Fixed>) {
    for (b, l) in w.iter_mut().enumerate().take(32) {
        if mask >> b & 1 != 0 && !l.is_const() {
            into.push((*l, value >> b & 1 != 0));
            *l = Lane::CONST;
        }
    }
}

/// One part of a [`Route`]: input `input` shifted left by `shift` (right when negative),
/// under `mask`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Part {
    input: u32,
    shift: i8,
    mask: u32,
}

/// How an output word comes from the inputs: its constant bits, the parts that are input
/// bits moved into place, and the bits inverted.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Route {
    konst: u32,
    invert: u32,
    parts: Vec<Part>,
}

impl Route {
    /// The route of a word recorded with `value` and lanes `w`.
    pub(crate) fn of(w: &Word, value: u32) -> Route {
        let mut r = Route::default();
        for (j, l) in w.iter().enumerate() {
            let Some((input, bit, inv)) = l.source() else {
                r.konst |= value & (1 << j);
                continue;
            };
            let shift = j as i8 - bit as i8;
            match r
                .parts
                .iter_mut()
                .find(|p| p.input == input && p.shift == shift)
            {
                Some(p) => p.mask |= 1 << j,
                None => r.parts.push(Part {
                    input,
                    shift,
                    mask: 1 << j,
                }),
            }
            if inv {
                r.invert |= 1 << j;
            }
        }
        r
    }

    /// Its word when it reads no input.
    pub(crate) fn constant(&self) -> Option<u32> {
        self.parts.is_empty().then_some(self.konst ^ self.invert)
    }

    /// The inputs it reads.
    pub(crate) fn inputs(&self) -> impl Iterator<Item = u32> + '_ {
        self.parts.iter().map(|p| p.input)
    }

    /// The word for inputs `inputs` (each a value by input number).
    pub(crate) fn eval(&self, inputs: &[u32]) -> u32 {
        let mut v = self.konst;
        for p in &self.parts {
            let x = inputs.get(p.input as usize).copied().unwrap_or(0);
            let x = match p.shift {
                s if s >= 0 => x << s,
                s => x >> -s,
            };
            v |= x & p.mask;
        }
        v ^ self.invert
    }
}

/// The constraints of a recording by input: (input, mask, value): the input's bits under
/// `mask` must be `value`.
pub(crate) fn constraints(fixed: &[Fixed]) -> Vec<(u32, u32, u32)> {
    let mut by: Vec<(u32, u32, u32)> = Vec::new();
    for &(l, v) in fixed {
        let Some((input, bit, inv)) = l.source() else {
            continue;
        };
        let value = u32::from(v != inv) << bit;
        match by.iter_mut().find(|c| c.0 == input) {
            Some(c) => {
                c.1 |= 1 << bit;
                c.2 |= value;
            }
            None => by.push((input, 1 << bit, value)),
        }
    }
    by.sort_unstable();
    by
}

/// Whether `fixed` contradicts itself (one input bit fixed both ways): such a recording
/// stands for no replay.
pub(crate) fn contradictory(fixed: &[Fixed]) -> bool {
    let mut seen: Vec<(u32, u32, bool)> = Vec::new();
    for &(l, v) in fixed {
        let Some((input, bit, inv)) = l.source() else {
            continue;
        };
        let want = v != inv;
        match seen.iter().find(|s| s.0 == input && s.1 == bit) {
            Some(s) if s.2 != want => return true,
            Some(_) => {}
            None => seen.push((input, bit, want)),
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_route_moves_and_inverts_input_bits_around_constants() {
        // Input 3's low byte, shifted left by 4 and inverted, over the constant 0xf00f.
        let w = not(&shl(&input_word(3, 8), 4));
        let recorded = 0xf00f | (!0x5au32 << 4 & 0xff0);
        let r = Route::of(&w, recorded);
        let mut inputs = vec![0; 4];
        inputs[3] = 0x5a;
        assert_eq!(r.eval(&inputs), recorded);
        inputs[3] = 0xc3;
        assert_eq!(r.eval(&inputs), 0xf00f | (!0xc3u32 << 4 & 0xff0));
        assert_eq!(r.parts.len(), 1);
        // Right shifts and reversal.
        let w = reverse(&input_word(1, 32));
        let r = Route::of(&w, 0);
        assert_eq!(r.eval(&[0, 0x1234_5678]), 0x1234_5678u32.reverse_bits());
        let w = shr(&input_word(0, 32), 20);
        assert_eq!(Route::of(&w, 0).eval(&[0xabcd_ef01]), 0xabcd_ef01 >> 20);
    }

    #[test]
    fn fixed_lanes_become_constraints_and_constants() {
        let mut w = not(&input_word(2, 4));
        let mut fixed = Vec::new();
        // The recorded value's bits 0–3 are 0b1010: input 2's were 0b0101.
        fix(&mut w, 0b1010, 0b0110, &mut fixed);
        assert!(w[1].is_const() && w[2].is_const() && !w[0].is_const());
        assert_eq!(constraints(&fixed), vec![(2, 0b0110, 0b0100)]);
        assert!(!contradictory(&fixed));
        fixed.push((Lane::input(2, 1), true));
        assert!(contradictory(&fixed));
    }
}
