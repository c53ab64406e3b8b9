//! The planner: the greedy sweep over contiguous key ranges ([`plan`]), with candidates
//! of one shape built once ([`Verdicts`]). Why the sweep is optimal, and why a shape's
//! verdict serves every candidate of it, is in the module documentation of
//! [`crate::boards`].

use super::{
    image_of, image_verdict, used_programs, BoardImage, BoardVerdict, BoardsError, KeyboardPlan,
    PlanInputs, PlanKey, ProgramCosts,
};
use crate::image::Program;
use crate::windows::MAX_KEYS;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::limiter::LimiterConfig;

/// A candidate board's verdict and, when it could be built, its image (what [`sweep`]
/// keeps of a board it chose).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Checked {
    pub(super) verdict: BoardVerdict,
    pub(super) image: Option<Arc<BoardImage>>,
}

/// Whether a candidate board fits ([`BoardVerdict::fits`]), for the search of [`greedy_end`]
/// over verdicts alone or verdicts with their images.
pub(super) trait Fits {
    fn fits(&self) -> bool;
}

impl Fits for BoardVerdict {
    fn fits(&self) -> bool {
        BoardVerdict::fits(self)
    }
}

impl Fits for Checked {
    fn fits(&self) -> bool {
        self.verdict.fits()
    }
}

/// [`check_board`](super::check_board) of `keys` with the image kept, the guard dropped only
/// when [`PlanInputs::may_drop_guard`] ([`image_of`]).
fn checked(inputs: PlanInputs, keys: &[PlanKey]) -> Result<Checked, BoardsError> {
    let (core_of, image) = image_of(inputs, keys)?;
    let verdict = image_verdict(inputs.programs, keys, inputs.board, &core_of, &image);
    Ok(Checked {
        verdict,
        image: image
            .ok()
            .map(|image| Arc::new(BoardImage { core_of, image })),
    })
}

/// What decides a candidate board's verdict but its keys' MIDI numbers, per key in key
/// order: the class of its program ([`Verdicts::new`]), the program's place among the
/// board's programs (in order of first use, as [`image_of`] numbers them), its costs
/// ([`ProgramCosts::key_cycles`], [`ProgramCosts::plain_key_cycles`]) and its window slots.
/// Two candidates of one shape get one layout, the same code in every bank and so the same
/// static bounds; they differ in their keys' param blocks only, which the image places
/// as data ([`Program::params`]: written into each key's state, never read by the WCET
/// analysis, and the same size within a class).
type Shape = Vec<(usize, usize, u64, u64, usize)>;

/// A built candidate's verdict and image (`None`: it has none), as [`Verdicts`] keeps it.
type Built = (BoardVerdict, Option<Arc<BoardImage>>);

/// The verdicts of the candidate boards a sweep has built, by [`Shape`], with the core of
/// each key and the image: a candidate of a shape already seen takes its verdict, its keys
/// renamed, and its image, its keys' param blocks written in
/// ([`FirmwareImage::with_params`]), instead of building and analysing the same image
/// again (the boards of a graded keyboard are mostly alike: grand88's 11 boards are one
/// shape).
struct Verdicts {
    /// Per program: the first program of its class, one that differs from it in its param
    /// block only (the same code and fixed-point program, the same flags).
    class: Vec<usize>,
    seen: Mutex<HashMap<Shape, Built>>,
    /// Whether verdicts are taken by shape (`false`: every candidate is built, as the tests
    /// that compare the two sweeps run it).
    on: bool,
}

impl Verdicts {
    fn new(programs: &[Program], on: bool) -> Verdicts {
        let alike = |a: &Program, b: &Program| {
            a.same_code(b)
                && Arc::ptr_eq(&a.fixed, &b.fixed)
                && a.params.len() == b.params.len()
                && a.quiescent_guard == b.quiescent_guard
                && a.sensor_check == b.sensor_check
                && a.watchdog == b.watchdog
        };
        let class = (0..programs.len())
            .map(|i| {
                (0..i)
                    .find(|&j| alike(&programs[j], &programs[i]))
                    .unwrap_or(i)
            })
            .collect();
        Verdicts {
            class,
            seen: Mutex::new(HashMap::new()),
            on,
        }
    }

    /// The shape of the board holding `keys`; `None` when a key's program does not exist
    /// (its check gives the error).
    fn shape(&self, costs: &ProgramCosts, keys: &[PlanKey]) -> Option<Shape> {
        let mut used: Vec<usize> = Vec::new();
        keys.iter()
            .map(|k| {
                let p = k.program;
                let local = used.iter().position(|&u| u == p).unwrap_or_else(|| {
                    used.push(p);
                    used.len() - 1
                });
                Some((
                    *self.class.get(p)?,
                    local,
                    *costs.key_cycles.get(p)?,
                    *costs.plain_key_cycles.get(p)?,
                    *costs.slots.get(p)?,
                ))
            })
            .collect()
    }

    /// [`checked`], or the verdict of a candidate of the same shape with `keys`' MIDI
    /// numbers and its image with `keys`' param blocks.
    fn checked(&self, inputs: PlanInputs, keys: &[PlanKey]) -> Result<Checked, BoardsError> {
        let check = || checked(inputs, keys);
        let Some(shape) = self.shape(inputs.costs, keys).filter(|_| self.on) else {
            return check();
        };
        let seen = || self.seen.lock().unwrap_or_else(|e| e.into_inner());
        let hit = seen().get(&shape).cloned();
        if let Some((mut verdict, built)) = hit {
            let core_of = built.as_ref().map_or(&[][..], |b| &b.core_of[..]);
            verdict.keys = keys.iter().map(|k| k.key).collect();
            for (c, core) in verdict.cores.iter_mut().enumerate() {
                core.keys = (keys.iter().zip(core_of))
                    .filter(|(_, &kc)| kc == c)
                    .map(|(k, _)| k.key)
                    .collect();
            }
            // The image's programs (the guard as it chose), with these keys' param blocks.
            let image = built.and_then(|b| {
                let local: Vec<Program> = (used_programs(keys).iter())
                    .zip(b.image.programs())
                    .map(|(&p, q)| q.with_params(inputs.programs[p].params.clone()))
                    .collect();
                let image = b.image.with_params(&local).ok()?;
                Some(Arc::new(BoardImage {
                    core_of: b.core_of.clone(),
                    image,
                }))
            });
            return Ok(Checked { verdict, image });
        }
        let c = check()?;
        seen().insert(shape, (c.verdict.clone(), c.image.clone()));
        Ok(c)
    }
}

/// The plan of a layout that lists its own boards (`lists`: the MIDI keys of each board):
/// each board's verdict as [`check_board`](super::check_board) gives it, with its image;
/// `progress(boards done, boards in all)`.
///
/// Errors: as [`board_image`](super::board_image).
pub fn check_boards(
    programs: &[Program],
    costs: &ProgramCosts,
    keys: &[PlanKey],
    lists: &[Vec<u8>],
    board: &BoardSpec,
    limiter: &LimiterConfig,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<KeyboardPlan, BoardsError> {
    let memo = Verdicts::new(programs, true);
    let inputs = PlanInputs::new(programs, costs, board, limiter);
    let mut out = Vec::with_capacity(lists.len());
    for (i, list) in lists.iter().enumerate() {
        progress(i, lists.len());
        let ks: Vec<PlanKey> = keys
            .iter()
            .filter(|k| list.contains(&k.key))
            .copied()
            .collect();
        out.push(memo.checked(inputs, &ks)?);
    }
    Ok(KeyboardPlan::of(out, false))
}

/// Plans the fewest boards for `keys` (ascending by key): contiguous ranges, each as long
/// as still fits (see the module documentation for why this is optimal). A key that does
/// not fit even alone gets a board of its own, which does not fit (the verdict says so).
/// `progress` is called with (keys placed, keys in all).
///
/// **The quiescent-key guard is a planned choice.** The sweep lets a board leave the guard
/// out where only that makes it fit ([`board_image`](super::board_image)), so the count is the fewest with or
/// without the guard. When some board of that plan leaves it out, the sweep runs again with
/// the guard kept on every board: if that plan has as many boards and all fit, it is the
/// plan (the guard cost no board, and idle keys stay cheap to run); otherwise the first
/// plan stands and its boards without the guard say so ([`BoardVerdict::guard_off`]).
///
/// Errors: as [`board_image`](super::board_image).
pub fn plan(
    programs: &[Program],
    costs: &ProgramCosts,
    keys: &[PlanKey],
    board: &BoardSpec,
    limiter: &LimiterConfig,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<KeyboardPlan, BoardsError> {
    plan_with(programs, costs, keys, board, limiter, true, progress)
}

/// [`plan`], its sweeps taking a candidate's verdict by shape ([`Verdicts`]) when `memo`.
pub(super) fn plan_with(
    programs: &[Program],
    costs: &ProgramCosts,
    keys: &[PlanKey],
    board: &BoardSpec,
    limiter: &LimiterConfig,
    memo: bool,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<KeyboardPlan, BoardsError> {
    let inputs = PlanInputs::new(programs, costs, board, limiter);
    let fewest = sweep(inputs, keys, None, memo, progress)?;
    if !fewest.iter().any(|b| b.verdict.guard_off) {
        return Ok(KeyboardPlan::of(fewest, true));
    }
    // The guarded plan counts only if it needs no more boards, all fitting: its sweep stops
    // as soon as it cannot be that plan. (Its boards all fit with the guard, so each image
    // is also what `board_image`, which drops the guard only where it does not fit, builds.)
    let guarded = sweep(
        PlanInputs {
            may_drop_guard: false,
            ..inputs
        },
        keys,
        Some(fewest.len()),
        memo,
        &mut |_, _| {},
    )?;
    let covered: usize = guarded.iter().map(|b| b.verdict.keys.len()).sum();
    if covered == keys.len()
        && guarded.len() <= fewest.len()
        && guarded.iter().all(|b| b.verdict.fits())
    {
        return Ok(KeyboardPlan::of(guarded, true));
    }
    Ok(KeyboardPlan::of(fewest, true))
}

/// The greedy sweep of [`plan`] over `keys`, boards without the guard allowed when
/// [`PlanInputs::may_drop_guard`].
///
/// Each board's end is the greedy one — the last key such that the board from its first
/// key to it fits — found by a search instead of one key at a time: because "fits" is
/// hereditary (module documentation), the fitting ends of a board are exactly those up to
/// the greedy end, so knowing that the range to `g` fits and the range to `g + 1` does not
/// is enough. The search starts from the previous board's key count (the boards of a
/// layout are mostly alike) and checks two candidate ends at a time (one on another
/// thread): usually one round a board instead of one per key. The plan, its verdicts and
/// its errors are those of the one-key-at-a-time sweep: a board's verdict is its greedy
/// range's, and an error is returned when that sweep would meet it (the range one key past
/// the greedy end); an error on a range that sweep never checks counts as "does not fit".
/// (Errors are per key — a key whose program does not exist — so every range holding an
/// erring key errs, and the one-key-at-a-time sweep meets the first such range.)
/// The first board's search starts from the keys its first key's program would fill by the
/// keys' own costs alone ([`ProgramCosts::plain_key_cycles`] against the cores' cycles).
///
/// With `most: Some(m)` the sweep stops, returning the boards so far, as soon as a board
/// does not fit or the plan would need more than `m` boards (the caller then has its
/// answer: not a plan of at most `m` fitting boards).
fn sweep(
    inputs: PlanInputs,
    keys: &[PlanKey],
    most: Option<usize>,
    memo: bool,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<Checked>, BoardsError> {
    let PlanInputs { costs, board, .. } = inputs;
    let memo = Verdicts::new(inputs.programs, memo);
    let check = |ks: &[PlanKey]| memo.checked(inputs, ks);
    let mut boards = Vec::new();
    let mut i = 0;
    let cycles = board
        .cycles_per_sample()
        .saturating_mul(u64::from(board.cores));
    let mut guess = keys
        .first()
        .and_then(|k| costs.plain_key_cycles.get(k.program))
        .map_or(1, |&c| {
            (cycles / c.max(1)).clamp(1, MAX_KEYS as u64) as usize
        });
    while i < keys.len() {
        if most.is_some_and(|m| boards.len() >= m) {
            break;
        }
        let (end, best) = greedy_end(&check, keys, i, guess)?;
        let fits = best.fits();
        boards.push(best);
        guess = end + 1 - i;
        i = end + 1;
        progress(i, keys.len());
        if most.is_some() && !fits {
            break;
        }
    }
    Ok(boards)
}

/// The greedy end of the board that starts at key `start` (the last index `e` such that
/// `keys[start..=e]` fits, `start` itself when not even one key fits) and that board's
/// verdict, searching from `start + guess − 1` with two checks a round ([`sweep`]).
///
/// Errors: the error of `keys[start..=e + 1]`'s check (or of `keys[start..=start]`'s when
/// one key does not fit), as the one-key-at-a-time sweep would meet it.
pub(super) fn greedy_end<T: Fits + Send>(
    check: &(dyn Fn(&[PlanKey]) -> Result<T, BoardsError> + Sync),
    keys: &[PlanKey],
    start: usize,
    guess: usize,
) -> Result<(usize, T), BoardsError> {
    let n = keys.len();
    // Checked ends and their answers; `lo` the last end known to fit (`None`: none yet),
    // `hi` the first end known not to (`n`: past the keys, which "does not fit").
    let mut seen: Vec<(usize, Result<T, BoardsError>)> = Vec::new();
    let fits = |r: &Result<T, BoardsError>| r.as_ref().is_ok_and(Fits::fits);
    let (mut lo, mut hi): (Option<usize>, usize) = (None, n);
    let mut next = (start + guess.max(1) - 1).min(n - 1);
    loop {
        // Two candidates among the unknown ends `floor..hi`: `next` and its neighbour.
        let floor = lo.map_or(start, |l| l + 1);
        let a = next.clamp(floor, hi - 1);
        let b = if a + 1 < hi {
            Some(a + 1)
        } else {
            a.checked_sub(1).filter(|&b| b >= floor)
        };
        let (ra, rb) = match b {
            Some(b) => {
                let (ra, rb) = rayon::join(|| check(&keys[start..=a]), || check(&keys[start..=b]));
                (ra, Some((b, rb)))
            }
            None => (check(&keys[start..=a]), None),
        };
        let mut all_fit = true;
        for (end, r) in std::iter::once((a, ra)).chain(rb) {
            if fits(&r) {
                lo = Some(lo.map_or(end, |l| l.max(end)));
            } else {
                hi = hi.min(end);
                all_fit = false;
            }
            seen.push((end, r));
        }
        match lo {
            Some(l) if l >= hi => return first_miss(check, keys, start),
            _ if lo.map_or(start, |l| l + 1) == hi => break,
            _ => {}
        }
        // Up from the last fit while the candidates fit, else down to just below the
        // first miss (the boards of a layout are mostly alike: one round settles).
        next = match (all_fit, lo) {
            (true, Some(l)) => l + 1,
            _ => hi.saturating_sub(2),
        };
    }
    let mut take = |end: usize| {
        let k = seen.iter().position(|(e, _)| *e == end)?;
        Some(seen.swap_remove(k).1)
    };
    match lo {
        Some(e) => {
            if let Some(Err(err)) = take(e + 1) {
                return Err(err);
            }
            // Checked by the search (which settles only on checked ends).
            let best = take(e).unwrap_or_else(|| check(&keys[start..=e]))?;
            Ok((e, best))
        }
        None => Ok((
            start,
            take(start).unwrap_or_else(|| check(&keys[start..=start]))?,
        )),
    }
}

/// The one-key-at-a-time answer of [`greedy_end`]: what the search falls back on when its
/// own checks show a range fitting beyond one that does not (which the module
/// documentation's argument excludes), so that it never settles on a contradiction.
pub(super) fn first_miss<T: Fits>(
    check: &(dyn Fn(&[PlanKey]) -> Result<T, BoardsError> + Sync),
    keys: &[PlanKey],
    start: usize,
) -> Result<(usize, T), BoardsError> {
    let mut best = check(&keys[start..=start])?;
    let mut end = start;
    while best.fits() && end + 1 < keys.len() {
        let next = check(&keys[start..=end + 1])?;
        if !next.fits() {
            break;
        }
        best = next;
        end += 1;
    }
    Ok((end, best))
}
