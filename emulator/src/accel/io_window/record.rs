//! Recording a window's replay for the period memo (`memo.rs`, "The period memo"): the
//! I/O run stepwise with lanes ([`crate::lanes`]: every data bit tagged with the input it
//! comes from), the DMA's SRAM reads and writes and bank claims logged, the parts' records
//! and the constraints (the data that decided something) kept, and the entry made unless
//! the recording breached a part's timing ([`Violation`]), read ROM or flash, or its
//! constraints contradict each other.

use super::*;

/// Why a replay failed (module documentation).
pub(super) enum Violation {
    Wait,
    Stale,
    Reach,
}

impl Drive<'_> {
    /// A miss of the period memo: the replay run with lanes (the I/O stepwise, each data
    /// word's lanes kept: `crate::lanes`) and the I/O run on to the window's `end`, then
    /// recorded when it is kept and stands for others (no timing breach of a part, no read
    /// of ROM or flash, no reset meanwhile). The I/O's checkpoint at `base` goes into `io`.
    pub(super) fn io_memo_record(
        &mut self,
        logs: &[Vec<IoAccess>; 2],
        banks: u8,
        own: u8,
        base: u64,
        end: u64,
        io: &mut Option<Checkpoint>,
    ) -> Result<(), Violation> {
        let to_memo = Rebase {
            from: base,
            to: Rebase::MEMO,
        };
        self.m.system.io_unlazy();
        let Some(now) = self.m.system.io.as_mut() else {
            return self.io_merge(logs, banks, own);
        };
        // Whether the window starts at the last entry's end (untouched since): the entry
        // recorded here then follows it.
        let linked = self.a.io_memo.after.is_some() && self.a.io_memo.after == Some(now.touches());
        let with_records = !now.records_full();
        let checkpoint = now.checkpoint();
        let mut start = checkpoint.io.clone();
        *io = Some(checkpoint);
        start.rebase(to_memo);
        start.data_slots(&mut |v, _| *v = 0);
        let counts = now.record_counts();
        let stepwise = std::mem::replace(&mut now.stepwise, true);
        let slots = now.start_lanes();
        // The data words whose lanes start as constants (known by the machine's invariants),
        // with their values.
        let mut start_const = Vec::with_capacity(slots as usize);
        now.data_slots(&mut |v, l| {
            start_const.push(
                l.is_some_and(|l| l.iter().all(|x| x.is_const()))
                    .then_some(*v),
            )
        });
        self.m.system.io_rec = Some(Box::new(LaneRec::new(slots)));
        let r = self.io_merge(logs, banks, own);
        if r.is_ok() {
            self.m.system.io_advance_to(end, true);
        }
        let rec = self.m.system.io_rec.take();
        let Some(now) = self.m.system.io.as_mut() else {
            return r;
        };
        now.stepwise = stepwise;
        now.forget_idle();
        let kept = now.stop_lanes();
        let (Ok(()), Some(kept), Some(rec)) = (&r, kept, rec) else {
            return r;
        };
        let records = now.records_since(&counts, to_memo);
        let mut fixed = kept.fixed;
        fixed.extend_from_slice(&rec.fixed);
        let (Some(records), false, false) = (records, rec.poisoned, lanes::contradictory(&fixed))
        else {
            return r;
        };
        let constraints = lanes::constraints(&fixed);
        let fixed_of = |input: u32| {
            constraints
                .iter()
                .find(|c| c.0 == input)
                .map_or((0, 0), |c| (c.1, c.2))
        };
        let ops: Vec<MemoOp> = (rec.ops.into_iter())
            .map(|op| match op {
                LaneOp::Read {
                    tick,
                    off,
                    size,
                    input,
                } => {
                    let (mask, value) = fixed_of(input);
                    MemoOp {
                        tick: tick - base,
                        off,
                        size,
                        kind: MemoOpKind::Read { mask, value },
                    }
                }
                LaneOp::Write {
                    tick,
                    off,
                    size,
                    value,
                    lanes,
                } => MemoOp {
                    tick: tick - base,
                    off,
                    size,
                    kind: MemoOpKind::Write {
                        route: Route::of(&lanes, value),
                    },
                },
            })
            .collect();
        // Every data word but those that end as they started (a hit keeps the live ones):
        // its own input, or a constant it held at the start too.
        let patches: Vec<(u32, Route)> = (kept.slots.iter().enumerate())
            .filter(|&(i, (v, w, bits))| {
                let own = (0..*bits as usize).all(|b| w[b] == Lane::input(i as u32, b as u32));
                let kept_const = start_const.get(i) == Some(&Some(*v)) && lanes::is_const(w);
                !(own || kept_const)
            })
            .map(|(i, (v, w, _))| (i as u32, Route::of(w, *v)))
            .collect();
        let (frame_routes, update_routes) = records.routes(&kept.frames, &kept.updates);
        let start_fixed: Vec<(u32, Option<Slot>, u32, u32)> = (constraints.iter())
            .filter(|c| c.0 < slots)
            .map(|&(i, m, v)| (i, now.locate(i as usize), m, v))
            .collect();
        // The data words at the start that the routes read.
        let mut needs: Vec<u32> = (ops.iter())
            .filter_map(|op| match &op.kind {
                MemoOpKind::Write { route } => Some(route),
                MemoOpKind::Read { .. } => None,
            })
            .chain(patches.iter().map(|(_, r)| r))
            .chain(frame_routes.iter().flatten())
            .chain(update_routes.iter().flatten())
            .flat_map(|r| r.inputs())
            .filter(|&i| i < slots)
            .collect();
        needs.sort_unstable();
        needs.dedup();
        let needs = (needs.into_iter())
            .map(|i| (i, now.locate(i as usize)))
            .collect();
        let (const_patches, patches): (Vec<_>, Vec<_>) = (patches.into_iter())
            .map(|(i, r)| (i, now.locate(i as usize), r))
            .partition(|(_, _, r)| r.constant().is_some());
        let const_patches = (const_patches.into_iter())
            .map(|(i, at, r)| (i, at, r.constant().unwrap_or(0)))
            .collect();
        let mut claims: Vec<(u64, u8)> = rec.claims.iter().map(|&(c, b)| (c - base, b)).collect();
        claims.sort_unstable();
        claims.dedup();
        let mut claimed = vec![0u64; claims.last().map_or(0, |c| c.0 as usize / 64 + 1)];
        for &(c, _) in &claims {
            claimed[c as usize / 64] |= 1 << (c % 64);
        }
        let at_cycle = at_cycle(&ops, &claims);
        let mut end_io = now.rebased(to_memo);
        end_io.forget_idle();
        let entry = MemoEntry {
            start_key: start.quick_key(Rebase {
                from: Rebase::MEMO,
                to: Rebase::MEMO,
            }),
            span: end.saturating_sub(base),
            xip: self.m.system.xip_answers,
            own,
            with_records,
            regs: reg_stores(logs, base),
            start,
            start_fixed,
            slots,
            needs,
            ops,
            claims,
            claimed,
            at_cycle,
            ran_to: now.cycle() - base,
            end: Arc::new(EndState::new(*end_io)),
            patches,
            const_patches,
            records,
            frame_routes,
            update_routes,
        };
        let entry = Arc::new(entry);
        if let Ok(mut shared) = SHARED.lock() {
            if shared.len() >= SHARED_ENTRIES {
                shared.remove(0);
            }
            shared.push(Arc::clone(&entry));
        }
        let at = self.a.io_memo.keep(entry);
        self.io_memo_followed_by(at, linked);
        self.a.io_windows.memo_recorded += 1;
        r
    }
}
