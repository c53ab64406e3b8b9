//! The replay's vocabulary, shared by every device that a window's replay or a period memo
//! (`accel/io_window/`) takes apart: time bases ([`Rebase`]: a recorded state's cycles
//! moved to where it is given again) and data words ([`Data`], [`Words`]).

use crate::lanes::{Lane, Word};

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

/// A part of the machine as a window's replay and the period memo see it: equal to another
/// but for its data words (each device's `data_slots`, the words a replay gives by their
/// routes), its cycles moved by a [`Rebase`] first; made another's but for its data words,
/// which stay; its cycles moved. Declared for each device once by [`replay_state!`], which
/// names every field with its role, or by hand for the few parts whose data words and
/// control share one field (the DMA's queue, an ADC's frame under way, a FIFO).
pub(crate) trait ReplayState {
    /// Whether `self`, its cycles moved by `r`, equals `other` but for data words.
    fn eq_but_data(&self, other: &Self, r: Rebase) -> bool;
    /// Becomes `other` but for its data words, which stay.
    fn assign_but_data(&mut self, other: &Self);
    /// Its cycles moved by `r`; its data words, records and notes not.
    fn rebase_cycles(&mut self, r: Rebase);
}

/// A cycle-valued field ([`replay_state!`]'s role `cycles`): compared after a [`Rebase`]
/// and moved by one.
pub(crate) trait Cycles {
    /// Whether `self` moved by `r` equals `other`.
    fn eq_at(&self, other: &Self, r: Rebase) -> bool;
    /// Moves it by `r`.
    fn move_by(&mut self, r: Rebase);
}

impl Cycles for u64 {
    #[inline]
    fn eq_at(&self, other: &Self, r: Rebase) -> bool {
        r.at(*self) == *other
    }
    #[inline]
    fn move_by(&mut self, r: Rebase) {
        *self = r.at(*self);
    }
}

impl Cycles for Option<u64> {
    #[inline]
    fn eq_at(&self, other: &Self, r: Rebase) -> bool {
        self.map(|c| r.at(c)) == *other
    }
    #[inline]
    fn move_by(&mut self, r: Rebase) {
        if let Some(c) = self {
            *c = r.at(*c);
        }
    }
}

/// A cycle and what happened then (a log's entry).
impl<T: PartialEq> Cycles for (u64, T) {
    #[inline]
    fn eq_at(&self, other: &Self, r: Rebase) -> bool {
        r.at(self.0) == other.0 && self.1 == other.1
    }
    #[inline]
    fn move_by(&mut self, r: Rebase) {
        self.0 = r.at(self.0);
    }
}

/// Arrays and `Vec`s of cycles and of parts, item by item (a `Vec`'s lengths compared too:
/// parts of one kind, as many on both sides, are assigned pairwise).
macro_rules! items {
    ($ty:ty $(, const $n:ident: usize)?) => {
        impl<T: Cycles $(, const $n: usize)?> Cycles for $ty {
            #[inline]
            fn eq_at(&self, other: &Self, r: Rebase) -> bool {
                self.len() == other.len() && self.iter().zip(other).all(|(a, b)| a.eq_at(b, r))
            }
            #[inline]
            fn move_by(&mut self, r: Rebase) {
                self.iter_mut().for_each(|c| c.move_by(r));
            }
        }

        impl<T: ReplayState $(, const $n: usize)?> ReplayState for $ty {
            #[inline]
            fn eq_but_data(&self, other: &Self, r: Rebase) -> bool {
                self.len() == other.len()
                    && self.iter().zip(other).all(|(a, b)| a.eq_but_data(b, r))
            }
            #[inline]
            fn assign_but_data(&mut self, other: &Self) {
                (self.iter_mut().zip(other)).for_each(|(a, b)| a.assign_but_data(b));
            }
            #[inline]
            fn rebase_cycles(&mut self, r: Rebase) {
                self.iter_mut().for_each(|x| x.rebase_cycles(r));
            }
        }
    };
}
items!([T; N], const N: usize);
items!(Vec<T>);

/// A part's data words ([`replay_state!`]'s roles `data`, `part` and `device`), visited in
/// a fixed order, each as a `u32` with its lanes while a replay is recorded
/// (`crate::lanes`): a device's `data_slots` (`crate::io::Io::data_slots`), which a period
/// memo compares machines without and a recorded replay gives by their routes.
pub(crate) trait Data {
    /// The lanes of its words, where its device keeps them (`()` for a device that keeps
    /// its own: role `device`).
    type Lanes;
    /// Gives `f` each data word in order with its lanes (from `lanes`, or its own), and
    /// keeps what `f` leaves there (cut to the word's width).
    fn visit(
        &mut self,
        lanes: Option<&mut Self::Lanes>,
        f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
    );
}

/// [`Data`] of a fixed number of words, each read and written by its place in the visit's
/// order (a period memo's patches, `accel/io_window/`).
pub(crate) trait Words: Data {
    /// How many words [`Data::visit`] gives.
    const WORDS: usize;
    /// Its `i`-th data word (0 past [`Words::WORDS`], or where the word has no place: an
    /// ADC's frame code without a frame).
    fn get(&self, i: usize) -> u32;
    /// Sets its `i`-th data word as the visit would (nothing past [`Words::WORDS`]).
    fn set(&mut self, i: usize, v: u32);
}

/// [`Words::WORDS`] of the field that `_field` reads, in a constant ([`replay_state!`]).
pub(crate) const fn words_of<S, T: Words>(_field: fn(&S) -> &T) -> usize {
    T::WORDS
}

/// A 32-bit data word (a register, a FIFO word), its lanes bit 0 first.
impl Data for u32 {
    type Lanes = Word;
    #[inline]
    fn visit(
        &mut self,
        lanes: Option<&mut Word>,
        f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
    ) {
        f(self, lanes.map(|l| &mut l[..]));
    }
}

impl Words for u32 {
    const WORDS: usize = 1;
    #[inline]
    fn get(&self, _: usize) -> u32 {
        *self
    }
    #[inline]
    fn set(&mut self, _: usize, v: u32) {
        *self = v;
    }
}

/// A 16-bit data word (a converter's code): its low 16 bits kept.
impl Data for u16 {
    type Lanes = [Lane; 16];
    #[inline]
    fn visit(
        &mut self,
        lanes: Option<&mut [Lane; 16]>,
        f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
    ) {
        let mut v = u32::from(*self);
        f(&mut v, lanes.map(|l| &mut l[..]));
        *self = v as u16;
    }
}

impl Words for u16 {
    const WORDS: usize = 1;
    #[inline]
    fn get(&self, _: usize) -> u32 {
        u32::from(*self)
    }
    #[inline]
    fn set(&mut self, _: usize, v: u32) {
        *self = v as u16;
    }
}

/// A one-bit data word (a level): its bit 0 kept.
impl Data for bool {
    type Lanes = Lane;
    #[inline]
    fn visit(
        &mut self,
        lanes: Option<&mut Lane>,
        f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
    ) {
        let mut v = u32::from(*self);
        f(&mut v, lanes.map(std::slice::from_mut));
        *self = v & 1 != 0;
    }
}

impl Words for bool {
    const WORDS: usize = 1;
    #[inline]
    fn get(&self, _: usize) -> u32 {
        u32::from(*self)
    }
    #[inline]
    fn set(&mut self, _: usize, v: u32) {
        *self = v & 1 != 0;
    }
}

/// Items in order, each with its lanes (the same index in `lanes`): an array's or a
/// `Vec`'s [`Data::visit`].
#[inline]
fn visit_items<T: Data>(
    items: &mut [T],
    lanes: Option<&mut [T::Lanes]>,
    f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
) {
    match lanes {
        Some(l) => (items.iter_mut().zip(l)).for_each(|(x, l)| x.visit(Some(l), f)),
        None => items.iter_mut().for_each(|x| x.visit(None, f)),
    }
}

/// An array's items in order, each with its lanes (the same index in the lanes' array).
impl<T: Data, const N: usize> Data for [T; N] {
    type Lanes = [T::Lanes; N];
    #[inline]
    fn visit(
        &mut self,
        lanes: Option<&mut Self::Lanes>,
        f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
    ) {
        visit_items(self, lanes.map(|l| &mut l[..]), f);
    }
}

impl<T: Words, const N: usize> Words for [T; N] {
    const WORDS: usize = N * T::WORDS;
    #[inline]
    fn get(&self, i: usize) -> u32 {
        <[T]>::get(self, i / T::WORDS).map_or(0, |x| x.get(i % T::WORDS))
    }
    #[inline]
    fn set(&mut self, i: usize, v: u32) {
        if let Some(x) = <[T]>::get_mut(self, i / T::WORDS) {
            x.set(i % T::WORDS, v);
        }
    }
}

/// A `Vec`'s items in order (as many as it holds: no [`Words`]), each with its lanes.
impl<T: Data> Data for Vec<T> {
    type Lanes = Vec<T::Lanes>;
    #[inline]
    fn visit(
        &mut self,
        lanes: Option<&mut Self::Lanes>,
        f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
    ) {
        visit_items(self, lanes.map(|l| &mut l[..]), f);
    }
}

/// [`ReplayState`] and [`Data`] for a device from one list naming each of its fields once
/// with its role (a field left out, or named twice, does not compile):
/// - `same`: control state, compared with `==` and assigned;
/// - `cycles`: cycle-valued ([`Cycles`]), compared after the rebase, assigned and moved;
/// - `part`: a part with its own [`ReplayState`] and [`Data`] (or an array or `Vec` of
///   them), its lanes in ours at the same name;
/// - `device`: as `part`, for a part that keeps its own lanes;
/// - `data`: data words ([`Data`]: `u32`, `u16`, `bool` or arrays of them), their lanes in
///   ours at the same name: neither compared nor assigned;
/// - `live`: compared, but the live machine's kept on assignment (how it runs, not what
///   it is);
/// - `hint`: a cycle-valued note to itself: not compared, but assigned and moved;
/// - `lanes`: the lanes kept while a replay records (`crate::lanes`): not compared, none
///   after an assignment;
/// - `skip`: not state (records, which only grow; counts of changes): left alone.
///
/// Its data words ([`Data::visit`]) are those of its fields of roles `data`, `part` and
/// `device` in the list's order: a field given one of them is a data slot, whatever else
/// is written by hand. Where its lanes are comes first: `[kept in FIELD: TYPE]`, its own
/// (`Option<Box<TYPE>>` at `FIELD`), or `[given: TYPE]`, in its device's; with `, words`
/// there, a part of a fixed number of words also gets [`Words`] (its words by index).
///
/// ```ignore
/// replay_state! { Dac8568 [kept in lanes: DacLanes, words] {
///     same: part, pins, clock_hz, lines, bits;
///     cycles: sync_fell, sync_rose, last_fall;
///     data: input, output, shift;
///     lanes: lanes;
///     skip: updates, violations, kept;
/// } }
/// ```
macro_rules! replay_state {
    ($ty:ident [kept in $own:ident: $lt:ty $(, $words:ident)?] $body:tt) => {
        $crate::replay::replay_state!(@state $ty $body);
        $crate::replay::replay_state!(@kept $ty, $own, $lt, $body);
        $($crate::replay::replay_state!(@$words $ty $body);)?
    };
    ($ty:ident [given: $lt:ty $(, $words:ident)?] $body:tt) => {
        $crate::replay::replay_state!(@state $ty $body);
        $crate::replay::replay_state!(@given $ty, $lt, $body);
        $($crate::replay::replay_state!(@$words $ty $body);)?
    };
    (@kept $ty:ident, $own:ident, $lt:ty, { $($role:ident: $($field:ident),+ ;)+ }) => {
        impl $crate::replay::Data for $ty {
            type Lanes = ();
            #[inline]
            fn visit(
                &mut self,
                _: Option<&mut ()>,
                f: &mut impl FnMut(&mut u32, Option<&mut [$crate::lanes::Lane]>),
            ) {
                let mut l: Option<&mut $lt> = self.$own.as_deref_mut();
                $($($crate::replay::replay_state!(@visit $role, self, l, f, $field);)+)+
                let _ = &mut l;
            }
        }
    };
    (@given $ty:ident, $lt:ty, { $($role:ident: $($field:ident),+ ;)+ }) => {
        impl $crate::replay::Data for $ty {
            type Lanes = $lt;
            #[inline]
            fn visit(
                &mut self,
                lanes: Option<&mut $lt>,
                f: &mut impl FnMut(&mut u32, Option<&mut [$crate::lanes::Lane]>),
            ) {
                let mut l = lanes;
                $($($crate::replay::replay_state!(@visit $role, self, l, f, $field);)+)+
                let _ = &mut l;
            }
        }
    };
    (@words $ty:ident { $($role:ident: $($field:ident),+ ;)+ }) => {
        impl $crate::replay::Words for $ty {
            const WORDS: usize = 0 $($(+ $crate::replay::replay_state!(@count $role, $ty, $field))+)+;
            #[inline]
            fn get(&self, i: usize) -> u32 {
                $($($crate::replay::replay_state!(@get $role, self, i, $field);)+)+
                let _ = i;
                0
            }
            #[inline]
            fn set(&mut self, i: usize, v: u32) {
                $($($crate::replay::replay_state!(@set $role, self, i, v, $field);)+)+
                let _ = (i, v);
            }
        }
    };
    (@state $ty:ident { $($role:ident: $($field:ident),+ ;)+ }) => {
        impl $crate::replay::ReplayState for $ty {
            #[inline]
            fn eq_but_data(&self, other: &Self, r: $crate::replay::Rebase) -> bool {
                let _ = r;
                // Every field named once: a field added must be given a role.
                let $ty { $($($field: _,)+)+ } = self;
                true $($(&& $crate::replay::replay_state!(@eq $role, self, other, r, $field))+)+
            }
            #[inline]
            fn assign_but_data(&mut self, other: &Self) {
                $($($crate::replay::replay_state!(@assign $role, self, other, $field);)+)+
            }
            #[inline]
            fn rebase_cycles(&mut self, r: $crate::replay::Rebase) {
                let _ = r;
                $($($crate::replay::replay_state!(@rebase $role, self, r, $field);)+)+
            }
        }
    };
    (@eq same, $a:ident, $b:ident, $r:ident, $f:ident) => { $a.$f == $b.$f };
    (@eq live, $a:ident, $b:ident, $r:ident, $f:ident) => { $a.$f == $b.$f };
    (@eq cycles, $a:ident, $b:ident, $r:ident, $f:ident) => {
        $crate::replay::Cycles::eq_at(&$a.$f, &$b.$f, $r)
    };
    (@eq part, $a:ident, $b:ident, $r:ident, $f:ident) => {
        $crate::replay::ReplayState::eq_but_data(&$a.$f, &$b.$f, $r)
    };
    (@eq device, $a:ident, $b:ident, $r:ident, $f:ident) => {
        $crate::replay::ReplayState::eq_but_data(&$a.$f, &$b.$f, $r)
    };
    (@eq data, $a:ident, $b:ident, $r:ident, $f:ident) => { true };
    (@eq hint, $a:ident, $b:ident, $r:ident, $f:ident) => { true };
    (@eq lanes, $a:ident, $b:ident, $r:ident, $f:ident) => { true };
    (@eq skip, $a:ident, $b:ident, $r:ident, $f:ident) => { true };
    (@assign same, $a:ident, $b:ident, $f:ident) => { $a.$f.clone_from(&$b.$f) };
    (@assign cycles, $a:ident, $b:ident, $f:ident) => { $a.$f.clone_from(&$b.$f) };
    (@assign hint, $a:ident, $b:ident, $f:ident) => { $a.$f.clone_from(&$b.$f) };
    (@assign part, $a:ident, $b:ident, $f:ident) => {
        $crate::replay::ReplayState::assign_but_data(&mut $a.$f, &$b.$f)
    };
    (@assign device, $a:ident, $b:ident, $f:ident) => {
        $crate::replay::ReplayState::assign_but_data(&mut $a.$f, &$b.$f)
    };
    (@assign lanes, $a:ident, $b:ident, $f:ident) => { $a.$f = None };
    (@assign data, $a:ident, $b:ident, $f:ident) => {};
    (@assign live, $a:ident, $b:ident, $f:ident) => {};
    (@assign skip, $a:ident, $b:ident, $f:ident) => {};
    (@rebase cycles, $a:ident, $r:ident, $f:ident) => {
        $crate::replay::Cycles::move_by(&mut $a.$f, $r)
    };
    (@rebase hint, $a:ident, $r:ident, $f:ident) => {
        $crate::replay::Cycles::move_by(&mut $a.$f, $r)
    };
    (@rebase part, $a:ident, $r:ident, $f:ident) => {
        $crate::replay::ReplayState::rebase_cycles(&mut $a.$f, $r)
    };
    (@rebase device, $a:ident, $r:ident, $f:ident) => {
        $crate::replay::ReplayState::rebase_cycles(&mut $a.$f, $r)
    };
    (@rebase same, $a:ident, $r:ident, $f:ident) => {};
    (@rebase live, $a:ident, $r:ident, $f:ident) => {};
    (@rebase data, $a:ident, $r:ident, $f:ident) => {};
    (@rebase lanes, $a:ident, $r:ident, $f:ident) => {};
    (@rebase skip, $a:ident, $r:ident, $f:ident) => {};
    // The data words: a field of role `data` or `part` visited with its lanes (ours at its
    // name), a `device` with its own; counted, read and written by index in that order.
    (@visit data, $s:ident, $l:ident, $f:ident, $x:ident) => {
        $crate::replay::Data::visit(&mut $s.$x, $l.as_deref_mut().map(|l| &mut l.$x), $f)
    };
    (@visit part, $s:ident, $l:ident, $f:ident, $x:ident) => {
        $crate::replay::Data::visit(&mut $s.$x, $l.as_deref_mut().map(|l| &mut l.$x), $f)
    };
    (@visit device, $s:ident, $l:ident, $f:ident, $x:ident) => {
        $crate::replay::Data::visit(&mut $s.$x, None, $f)
    };
    (@visit $role:ident, $s:ident, $l:ident, $f:ident, $x:ident) => {};
    (@count data, $ty:ident, $x:ident) => { $crate::replay::words_of(|s: &$ty| &s.$x) };
    (@count part, $ty:ident, $x:ident) => { $crate::replay::words_of(|s: &$ty| &s.$x) };
    (@count device, $ty:ident, $x:ident) => { $crate::replay::words_of(|s: &$ty| &s.$x) };
    (@count $role:ident, $ty:ident, $x:ident) => { 0 };
    (@get data, $s:ident, $i:ident, $x:ident) => { $crate::replay::replay_state!(@get_word $s, $i, $x); };
    (@get part, $s:ident, $i:ident, $x:ident) => { $crate::replay::replay_state!(@get_word $s, $i, $x); };
    (@get device, $s:ident, $i:ident, $x:ident) => { $crate::replay::replay_state!(@get_word $s, $i, $x); };
    (@get $role:ident, $s:ident, $i:ident, $x:ident) => {};
    (@get_word $s:ident, $i:ident, $x:ident) => {
        let $i = {
            let n = $crate::replay::words_of(|s: &Self| &s.$x);
            if $i < n {
                return $crate::replay::Words::get(&$s.$x, $i);
            }
            $i - n
        };
    };
    (@set data, $s:ident, $i:ident, $v:ident, $x:ident) => { $crate::replay::replay_state!(@set_word $s, $i, $v, $x); };
    (@set part, $s:ident, $i:ident, $v:ident, $x:ident) => { $crate::replay::replay_state!(@set_word $s, $i, $v, $x); };
    (@set device, $s:ident, $i:ident, $v:ident, $x:ident) => { $crate::replay::replay_state!(@set_word $s, $i, $v, $x); };
    (@set $role:ident, $s:ident, $i:ident, $v:ident, $x:ident) => {};
    (@set_word $s:ident, $i:ident, $v:ident, $x:ident) => {
        let $i = {
            let n = $crate::replay::words_of(|s: &Self| &s.$x);
            if $i < n {
                return $crate::replay::Words::set(&mut $s.$x, $i, $v);
            }
            $i - n
        };
    };
}
pub(crate) use replay_state;
