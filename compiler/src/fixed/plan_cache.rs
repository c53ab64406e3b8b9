//! The on-disk cache of the planner's simulated search
//! (`FixedProgram::spend_by_simulation`): the product forms it chose for a program, so that
//! the next process planning the same program (every `tactus play`, `budget` or `build` of a
//! piano) reads them instead of simulating again (≈ 26 CPU-s for the piano in a debug
//! build, ≈ 3 × that for grand88's shared program).
//!
//! **Key.** SHA3-256 of the planner's inputs (the plan configuration and the whole IR
//! program, as printed by `Debug`) and of every source of this crate but the Thumb backend
//! (which only reads plans) and of the runtime (`TACTUS_PLANNER_SOURCE_SHA3`, computed by
//! `build.rs`), so a changed planner never reads an older planner's choice. The entry is only a memo of a deterministic computation: with
//! or without it the plan is the same.
//!
//! **Where.** `$TACTUS_CACHE_DIR`, else `$XDG_CACHE_HOME/tactus`, else `$HOME/.cache/tactus`,
//! in `plans/`. `TACTUS_CACHE_DIR=off` turns the cache off.
//!
//! **Failures.** None is an error: an unreadable, malformed or mismatched entry is a miss
//! (the search runs and rewrites it); a directory that cannot be written leaves the plan
//! uncached. An entry is written to a temporary file and renamed into place, so processes
//! running at once never read half an entry.
//!
//! **One search per program** ([`searched_once`]). Threads of one process and processes
//! running at once (the test binaries' parallel tests, the CLI runs a test spawns side by
//! side) that ask for the same program wait for the one search that runs instead of each
//! running it: a per-process slot per key, and across processes an exclusive `flock` on the
//! entry's `.lock` file (released by the kernel when its process ends, so a crashed search
//! never blocks another). The empty `.lock` files stay: one removed while another process waits
//! on it would let a third process lock a new file and search at the same time. Without a
//! cache directory only the per-process slot applies.

use super::{Cut, MulKind};
use sha3::{Digest, Sha3_256};
use std::path::{Path, PathBuf};

/// First line of an entry: the format's version.
const MAGIC: &str = "tactus-plan-forms 1";

/// The cache directory, or `None` when turned off or when no home is known.
fn dir() -> Option<PathBuf> {
    let base = match std::env::var_os("TACTUS_CACHE_DIR") {
        Some(d) if d == "off" => return None,
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => match std::env::var_os("XDG_CACHE_HOME") {
            Some(d) if !d.is_empty() => PathBuf::from(d).join("tactus"),
            _ => PathBuf::from(std::env::var_os("HOME")?).join(".cache/tactus"),
        },
    };
    Some(base.join("plans"))
}

/// The entry's file name for the planner's input `key` (hex SHA3-256, see the module doc).
fn file_name(key: &str) -> String {
    let mut h = Sha3_256::new();
    h.update(env!("TACTUS_PLANNER_SOURCE_SHA3").as_bytes());
    h.update(key.as_bytes());
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    format!("{hex}.forms")
}

/// One value's form as a token: `-` (not a product), `m A B`, `t C B K` (32×16: `C` the
/// cut operand, 1 or 2), `h K`, `w`.
fn encode(k: &Option<MulKind>) -> String {
    match k {
        None => "-".into(),
        Some(MulKind::Muls(a, b)) => format!("m {a} {b}"),
        Some(MulKind::Mul32x16 { cut, b, k }) => {
            let c = match cut {
                Cut::First => 1,
                Cut::Second => 2,
            };
            format!("t {c} {b} {k}")
        }
        Some(MulKind::High(k)) => format!("h {k}"),
        Some(MulKind::Wide) => "w".into(),
    }
}

fn decode(line: &str) -> Option<Option<MulKind>> {
    let mut t = line.split(' ');
    let k = match t.next()? {
        "-" => None,
        "m" => Some(MulKind::Muls(
            t.next()?.parse().ok()?,
            t.next()?.parse().ok()?,
        )),
        "t" => {
            let cut = match t.next()? {
                "1" => Cut::First,
                "2" => Cut::Second,
                _ => return None,
            };
            Some(MulKind::Mul32x16 {
                cut,
                b: t.next()?.parse().ok()?,
                k: t.next()?.parse().ok()?,
            })
        }
        "h" => Some(MulKind::High(t.next()?.parse().ok()?)),
        "w" => Some(MulKind::Wide),
        _ => return None,
    };
    t.next().is_none().then_some(k)
}

/// The forms for the planner's input `key`: from this process' memo, else from the disk
/// entry, else from `search` (then stored in both). `like` is the plan the search starts from
/// (an entry of another shape is a miss). At most one `search` per key runs at a time in this
/// process, and, with a cache directory, in every process sharing it; the others wait for it
/// and read its result.
pub(crate) fn searched_once(
    key: &str,
    like: &[Option<MulKind>],
    search: impl FnOnce() -> Vec<Option<MulKind>>,
) -> Vec<Option<MulKind>> {
    computed_once(
        key,
        MAGIC,
        |body| parse_forms(body, like),
        |k: &Vec<_>| render_forms(k),
        search,
    )
}

/// The contract's verdict on a planned program (`contract::verdict`), memoised like the
/// forms: `key` is the program the verdict is about (its IR, from which the plan follows),
/// `check` computes the verdict (`None`: holds; `Some((stimulus, violations))`).
pub(crate) fn verdict_once(
    key: &str,
    check: impl FnOnce() -> Option<(String, Vec<String>)>,
) -> Option<(String, Vec<String>)> {
    computed_once(
        &format!("contract verdict\n{key}"),
        VERDICT_MAGIC,
        |body| match body {
            "holds" => Some(None),
            _ => {
                let mut lines = body.lines();
                let stim = lines.next()?.strip_prefix("broken ")?.to_string();
                Some(Some((stim, lines.map(str::to_string).collect())))
            }
        },
        |v| match v {
            None => "holds".to_string(),
            Some((stim, why)) => {
                let mut t = format!("broken {stim}");
                for w in why {
                    t.push('\n');
                    t.push_str(&w.replace('\n', " "));
                }
                t
            }
        },
        check,
    )
}

/// First line of a verdict entry.
const VERDICT_MAGIC: &str = "tactus-contract-verdict 1";

/// The one memo behind [`searched_once`] and [`verdict_once`]: the value for `key` from
/// this process' memo, else from the disk entry (first line `magic`, then `render`'s text,
/// read by `parse`), else from `compute` (then stored in both); one `compute` per key at a
/// time in this process and, with a cache directory, across processes.
fn computed_once<T>(
    key: &str,
    magic: &str,
    parse: impl Fn(&str) -> Option<T>,
    render: impl Fn(&T) -> String,
    compute: impl FnOnce() -> T,
) -> T {
    type Slot = std::sync::Arc<std::sync::Mutex<Option<String>>>;
    static SLOTS: std::sync::OnceLock<std::sync::Mutex<std::collections::HashMap<String, Slot>>> =
        std::sync::OnceLock::new();
    let slot: Slot = {
        let mut slots = SLOTS
            .get_or_init(Default::default)
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        slots.entry(format!("{magic}\n{key}")).or_default().clone()
    };
    // Held for the whole computation: this process' other threads asking for `key` wait here.
    let mut memo = slot.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(v) = memo.as_deref().and_then(&parse) {
        return v;
    }
    let dir = dir();
    let from_disk = |memo: &mut Option<String>| {
        let body = load_text(dir.as_deref()?, key, magic)?;
        let v = parse(&body)?;
        *memo = Some(body);
        Some(v)
    };
    if let Some(v) = from_disk(&mut memo) {
        return v;
    }
    // Other processes: the entry's lock file, then the entry again (the computation that
    // held the lock may have just written it). A lock that cannot be taken only costs a
    // computation.
    let _lock = dir.as_deref().and_then(|d| lock_in(d, key));
    if let Some(v) = from_disk(&mut memo) {
        return v;
    }
    let v = compute();
    let body = render(&v);
    if let Some(d) = dir.as_deref() {
        store_text(d, key, magic, &body);
    }
    *memo = Some(body);
    v
}

/// An exclusive lock on `key`'s lock file in `dir` (blocking until the process holding it
/// releases it or ends), or `None` when the file cannot be created or locked.
fn lock_in(dir: &Path, key: &str) -> Option<std::fs::File> {
    std::fs::create_dir_all(dir).ok()?;
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(dir.join(format!("{}.lock", file_name(key))))
        .ok()?;
    file.lock().ok()?;
    Some(file)
}

/// The body of `key`'s entry in `dir` when its first line is `magic`.
fn load_text(dir: &Path, key: &str, magic: &str) -> Option<String> {
    let text = std::fs::read_to_string(dir.join(file_name(key))).ok()?;
    let (first, body) = text.split_once('\n').unwrap_or((&text, ""));
    (first == magic).then(|| body.to_string())
}

/// Forms read from an entry's body: one per value of `like` and a product exactly where
/// `like` has one; otherwise `None`.
fn parse_forms(body: &str, like: &[Option<MulKind>]) -> Option<Vec<Option<MulKind>>> {
    let kinds: Vec<Option<MulKind>> = body.lines().map(decode).collect::<Option<_>>()?;
    let same_shape = kinds.len() == like.len()
        && kinds
            .iter()
            .zip(like)
            .all(|(a, b)| a.is_some() == b.is_some());
    same_shape.then_some(kinds)
}

fn render_forms(kinds: &[Option<MulKind>]) -> String {
    kinds.iter().map(encode).collect::<Vec<_>>().join("\n")
}

#[cfg(test)]
/// The forms cached for `key` in `dir`, if an entry exists with one form per value of `like` and a
/// product exactly where `like` has one; otherwise `None`.
fn load_in(dir: &Path, key: &str, like: &[Option<MulKind>]) -> Option<Vec<Option<MulKind>>> {
    parse_forms(&load_text(dir, key, MAGIC)?, like)
}

#[cfg(test)]
/// Stores `kinds` for `key` in `dir`; silently does nothing when it cannot be written.
fn store_in(dir: &Path, key: &str, kinds: &[Option<MulKind>]) {
    store_text(dir, key, MAGIC, &render_forms(kinds));
}

/// Stores `magic` and `body` as `key`'s entry in `dir` (through a temporary file, renamed
/// into place); silently does nothing when it cannot be written.
fn store_text(dir: &Path, key: &str, magic: &str, body: &str) {
    if std::fs::create_dir_all(dir).is_err() {
        return;
    }
    let name = file_name(key);
    let tmp = dir.join(format!("{name}.{}.tmp", std::process::id()));
    if std::fs::write(&tmp, format!("{magic}\n{body}")).is_ok()
        && std::fs::rename(&tmp, dir.join(&name)).is_err()
    {
        let _ = std::fs::remove_file(&tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// The names `pattern` (`tactus_runtime::` or `crate::`) is followed by in the `.rs`
    /// files under `path`.
    fn modules_named(path: &std::path::Path, pattern: &str, out: &mut BTreeSet<String>) {
        let files: Vec<std::path::PathBuf> = match path.is_dir() {
            true => std::fs::read_dir(path)
                .unwrap()
                .map(|e| e.unwrap().path())
                .collect(),
            false => vec![path.to_path_buf()],
        };
        for f in files {
            if f.is_dir() {
                modules_named(&f, pattern, out);
                continue;
            }
            if f.extension().is_none_or(|x| x != "rs") {
                continue;
            }
            let text = std::fs::read_to_string(&f).unwrap();
            for (i, _) in text.match_indices(pattern) {
                let name: String = text[i + pattern.len()..]
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    out.insert(name);
                }
            }
        }
    }

    #[test]
    fn planner_key_covers_every_runtime_module_the_compiler_uses() {
        // The cache key (build.rs) hashes the compiler's sources and these runtime files:
        // every runtime module the compiler names, and every one those name in turn, must
        // be among them, or a change there would keep stale plans.
        let listed: BTreeSet<String> = env!("TACTUS_PLANNER_RUNTIME_MODULES")
            .split(',')
            .map(|m| m.trim_end_matches(".rs").to_string())
            .collect();
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let runtime = root.join("../runtime/src");
        let mut used = BTreeSet::new();
        modules_named(&root.join("src"), "tactus_runtime::", &mut used);
        // Constants at the runtime's root (`DEFAULT_SAMPLE_RATE_HZ`) are in lib.rs.
        used.retain(|m| runtime.join(format!("{m}.rs")).is_file() || runtime.join(m).is_dir());
        assert!(
            used.contains("fixed") && used.contains("stimulus"),
            "{used:?}"
        );
        let mut todo: Vec<String> = used.iter().cloned().collect();
        while let Some(m) = todo.pop() {
            let path = match runtime.join(&m).is_dir() {
                true => runtime.join(&m),
                false => runtime.join(format!("{m}.rs")),
            };
            let mut next = BTreeSet::new();
            modules_named(&path, "crate::", &mut next);
            for n in next {
                let is_module =
                    runtime.join(format!("{n}.rs")).is_file() || runtime.join(&n).is_dir();
                if is_module && used.insert(n.clone()) {
                    todo.push(n);
                }
            }
        }
        let missing: Vec<&String> = used.iter().filter(|m| !listed.contains(*m)).collect();
        assert!(
            missing.is_empty(),
            "runtime modules the planner reads but its cache key (compiler/build.rs RUNTIME_MODULES) leaves out: {missing:?}"
        );
        assert!(listed.contains("lib"), "{listed:?}");
    }

    #[test]
    fn every_form_round_trips_and_garbage_is_a_miss() {
        let kinds = [
            None,
            Some(MulKind::Muls(3, 15)),
            Some(MulKind::High(17)),
            Some(MulKind::Mul32x16 {
                cut: Cut::First,
                b: 16,
                k: 9,
            }),
            Some(MulKind::Mul32x16 {
                cut: Cut::Second,
                b: 0,
                k: 16,
            }),
            Some(MulKind::Wide),
        ];
        for k in &kinds {
            assert_eq!(decode(&encode(k)), Some(*k));
        }
        for bad in [
            "",
            "x",
            "m 1",
            "m 1 2 3",
            "h 300",
            "w 1",
            "t 3 1 1",
            "t 1 1",
            "t 2 1 1 1",
        ] {
            assert_eq!(decode(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn an_entry_is_read_back_only_for_its_key_and_shape() {
        let dir = std::env::temp_dir().join(format!("tactus-plan-cache-{}", std::process::id()));
        let kinds = vec![None, Some(MulKind::High(16)), Some(MulKind::Wide)];
        store_in(&dir, "program A", &kinds);
        assert_eq!(load_in(&dir, "program A", &kinds), Some(kinds.clone()));
        assert_eq!(load_in(&dir, "program B", &kinds), None);
        assert_eq!(load_in(&dir, "program A", &kinds[..2]), None);
        let shifted = vec![Some(MulKind::Wide), None, Some(MulKind::Wide)];
        assert_eq!(load_in(&dir, "program A", &shifted), None);
        std::fs::write(dir.join(file_name("program C")), "junk").unwrap();
        assert_eq!(load_in(&dir, "program C", &kinds), None);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn threads_asking_for_one_program_share_one_search() {
        // A key no other test uses, so the memo starts empty for it.
        let key = format!("one search {}", std::process::id());
        let like = vec![None, Some(MulKind::Wide)];
        let searches = std::sync::atomic::AtomicUsize::new(0);
        let results: Vec<Vec<Option<MulKind>>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..4)
                .map(|_| {
                    s.spawn(|| {
                        searched_once(&key, &like, || {
                            searches.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                            std::thread::sleep(std::time::Duration::from_millis(50));
                            vec![None, Some(MulKind::High(16))]
                        })
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert_eq!(searches.load(std::sync::atomic::Ordering::SeqCst), 1);
        assert!(results
            .iter()
            .all(|r| r == &vec![None, Some(MulKind::High(16))]));
    }

    #[test]
    fn a_held_lock_blocks_another_holder_until_released() {
        let dir = std::env::temp_dir().join(format!("tactus-plan-lock-{}", std::process::id()));
        let first = lock_in(&dir, "program L").expect("a lock in a writable directory");
        let (tx, rx) = std::sync::mpsc::channel();
        let d = dir.clone();
        let waiter = std::thread::spawn(move || {
            let second = lock_in(&d, "program L");
            tx.send(second.is_some()).unwrap();
        });
        // The second lock (another open file description: as another process) waits.
        assert!(rx
            .recv_timeout(std::time::Duration::from_millis(200))
            .is_err());
        drop(first);
        assert_eq!(
            rx.recv_timeout(std::time::Duration::from_secs(10)),
            Ok(true)
        );
        waiter.join().unwrap();
        let _ = std::fs::remove_dir_all(&dir);
    }
}
