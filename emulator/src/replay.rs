//! The replay's vocabulary, shared by every device that a window's replay or a period memo
//! (`accel/io_window/`) takes apart: time bases ([`Rebase`]: a recorded state's cycles
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

/// [`ReplayState`] for a device from one list naming each of its fields once with its role
/// (a field left out, or named twice, does not compile):
/// - `same`: control state, compared with `==` and assigned;
/// - `cycles`: cycle-valued ([`Cycles`]), compared after the rebase, assigned and moved;
/// - `part`: a part with its own [`ReplayState`] (or an array or `Vec` of them);
/// - `data`: data words (the device's `data_slots`): neither compared nor assigned;
/// - `live`: compared, but the live machine's kept on assignment (how it runs, not what
///   it is);
/// - `hint`: a cycle-valued note to itself: not compared, but assigned and moved;
/// - `lanes`: the lanes kept while a replay records (`crate::lanes`): not compared, none
///   after an assignment;
/// - `skip`: not state (records, which only grow; counts of changes): left alone.
///
/// ```ignore
/// replay_state! { Dac8568 {
///     same: part, pins, clock_hz, lines, bits;
///     cycles: sync_fell, sync_rose, last_fall;
///     data: input, output, shift;
///     lanes: lanes;
///     skip: updates, violations, kept;
/// } }
/// ```
macro_rules! replay_state {
    ($ty:ident { $($role:ident: $($field:ident),+ ;)+ }) => {
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
    (@rebase same, $a:ident, $r:ident, $f:ident) => {};
    (@rebase live, $a:ident, $r:ident, $f:ident) => {};
    (@rebase data, $a:ident, $r:ident, $f:ident) => {};
    (@rebase lanes, $a:ident, $r:ident, $f:ident) => {};
    (@rebase skip, $a:ident, $r:ident, $f:ident) => {};
}
pub(crate) use replay_state;
