//! The format plan of each open profile, computed on a worker thread.
//!
//! `FixedProgram::new` is the plan every build uses (the precision budget, checked by
//! simulating the accuracy contract; cached on disk by the program's hash): milliseconds
//! when cached, up to minutes for a large profile the cache has not seen. So the main loop
//! never waits for it except briefly in a hover, and a newer version of a document
//! replaces an older one still queued.

use crossbeam_channel::{Receiver, Sender};
use std::sync::Arc;
use tactus_compiler::fixed::{report, FixedProgram};
use tactus_compiler::ir::Program;

/// A finished plan and its error bounds.
pub struct Planned {
    /// The plan.
    pub fixed: FixedProgram,
    /// Its precision report.
    pub precision: report::Precision,
}

/// A plan request: (document, generation, program).
type Request = (String, u64, Program);

/// A plan result: (document, generation, the plan or why there is none).
pub type Done = (String, u64, Result<Arc<Planned>, String>);

/// The worker: send programs, receive plans.
pub struct Planner {
    requests: Sender<Request>,
    /// Finished plans.
    pub done: Receiver<Done>,
}

impl Planner {
    /// Starts the worker thread; it ends when the planner is dropped.
    pub fn start() -> Self {
        let (requests, inbox) = crossbeam_channel::unbounded::<Request>();
        let (results, done) = crossbeam_channel::unbounded::<Done>();
        let spawned = std::thread::Builder::new()
            .name("tactus-lsp-plan".into())
            .spawn(move || {
                while let Ok(first) = inbox.recv() {
                    // Only the newest request of each document is worth planning.
                    let mut batch = vec![first];
                    batch.extend(inbox.try_iter());
                    let mut newest: Vec<Request> = Vec::new();
                    for r in batch {
                        match newest.iter_mut().find(|n| n.0 == r.0) {
                            Some(n) if n.1 < r.1 => *n = r,
                            Some(_) => {}
                            None => newest.push(r),
                        }
                    }
                    for (uri, generation, program) in newest {
                        let planned = std::panic::catch_unwind(|| {
                            let fixed = FixedProgram::new(&program);
                            let precision = report::analyse(&fixed);
                            Arc::new(Planned { fixed, precision })
                        })
                        .map_err(|_| "the format plan failed (a compiler bug)".to_string());
                        if results.send((uri, generation, planned)).is_err() {
                            return;
                        }
                    }
                }
            });
        // Without the thread (the system refused one), requests go nowhere: hovers say the
        // plan is not ready.
        let _ = spawned;
        Planner { requests, done }
    }

    /// Asks for the plan of `program` as generation `generation` of document `uri`.
    pub fn request(&self, uri: &str, generation: u64, program: Program) {
        let _ = self.requests.send((uri.to_string(), generation, program));
    }
}
