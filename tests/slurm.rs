//! Issue 73: the example job array (`examples/slurm/corpus.sbatch`) on a real Slurm. The test
//! starts its own cluster on this machine — munged, slurmctld and slurmd from Debian's
//! `munge` and `slurm-wlm`, one node of 2 CPUs on localhost without cgroups, in a temporary
//! directory with its own key, ports and state — submits the script as a 2-task array over
//! two short pieces on the emulated boards, waits for the tasks and the merge job the first
//! task submits, and compares the merged tables with one machine's run. Every daemon it
//! started is stopped when it ends, passed or failed ([`Cluster`]'s `Drop`).
//!
//! Without the tools, or when the cluster does not come up, it says SKIPPED — and fails
//! when `CI` is set (`.ci/run` installs them).

mod common;
use common::{assert_ok, small_layout, tactus, temp_dir, without_timings, write_midi};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Fails under `CI`, else says SKIPPED; `None` to return from the test.
fn skip(why: &str) -> Option<()> {
    assert!(
        std::env::var_os("CI").is_none(),
        "{why}: CI is set, so this test fails rather than skips"
    );
    eprintln!("SKIPPED: {why}");
    None
}

/// A path to `name` on the PATH or in /usr/sbin (where Debian puts the daemons).
fn tool(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin".into(), "/usr/bin".into()])
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// A free TCP port on localhost (bound, then released for the daemon).
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .unwrap()
}

/// A one-node Slurm cluster and its munged, each daemon a child in the foreground; dropped,
/// it cancels every job and stops the daemons it started (by their process ids).
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
    daemons: Vec<(&'static str, Child)>,
}

impl Cluster {
    /// A command of the cluster (`sbatch`, `squeue`, …) that finds its configuration.
    fn command(&self, name: &str) -> Command {
        let mut c = Command::new(tool(name).unwrap_or_else(|| name.into()));
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// The text of a command's standard output ("" when it fails).
    fn ask(&self, name: &str, args: &[&str]) -> String {
        self.command(name)
            .args(args)
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
            .unwrap_or_default()
    }

    /// The daemons' logs, for a failure's message.
    fn logs(&self) -> String {
        ["munged.log", "slurmctld.log", "slurmd.log"]
            .iter()
            .map(|f| {
                let t = std::fs::read_to_string(self.dir.join(f)).unwrap_or_default();
                let tail: Vec<&str> = t.lines().rev().take(15).collect();
                format!(
                    "--- {f}:\n{}",
                    tail.into_iter().rev().collect::<Vec<_>>().join("\n")
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Starts a daemon in the foreground, its output to `NAME.out`.
    fn spawn(&mut self, name: &'static str, args: &[&str]) -> Result<(), String> {
        let log = std::fs::File::create(self.dir.join(format!("{name}.out")))
            .map_err(|e| e.to_string())?;
        let child = Command::new(tool(name).ok_or(format!("no {name}"))?)
            .args(args)
            .env("SLURM_CONF", &self.conf)
            .stdin(Stdio::null())
            .stdout(log.try_clone().map_err(|e| e.to_string())?)
            .stderr(log)
            .spawn()
            .map_err(|e| format!("{name}: {e}"))?;
        self.daemons.push((name, child));
        Ok(())
    }

    /// Starts munged, slurmctld and slurmd in `dir` and waits for the node to be idle.
    fn start(dir: &Path) -> Result<Cluster, (Option<Cluster>, String)> {
        let user = Command::new("id")
            .arg("-un")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
            .map_err(|e| (None, format!("id -un: {e}")))?;
        let key = dir.join("munge.key");
        let mut random = vec![0u8; 1024];
        std::fs::File::open("/dev/urandom")
            .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut random))
            .and_then(|()| std::fs::write(&key, &random))
            .map_err(|e| (None, format!("munge key: {e}")))?;
        use std::os::unix::fs::PermissionsExt;
        let _ = std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o400));
        let _ = std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o755));
        let socket = dir.join("munge.socket");
        let conf = dir.join("slurm.conf");
        let (ctld_port, d_port) = (free_port(), free_port());
        let d = dir.display();
        std::fs::create_dir_all(dir.join("state")).map_err(|e| (None, e.to_string()))?;
        std::fs::create_dir_all(dir.join("spool")).map_err(|e| (None, e.to_string()))?;
        // The node's memory as the machine has it (most of it): memory is not a consumable
        // resource here (CR_CPU), but a job's --mem must fit the node.
        let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap_or_default();
        let mem_mb = (meminfo.lines())
            .find_map(|l| l.strip_prefix("MemTotal:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .map_or(2048, |kb| kb / 1024 * 9 / 10);
        // One node, 2 CPUs, no cgroups: process tracking by the process tree, no task
        // binding, no accounting.
        let text = format!(
            "ClusterName=tactus\n\
             SlurmctldHost=localhost(127.0.0.1)\n\
             SlurmUser={user}\nSlurmdUser={user}\n\
             SlurmctldPort={ctld_port}\nSlurmdPort={d_port}\n\
             AuthType=auth/munge\nCredType=cred/munge\nAuthInfo=socket={d}/munge.socket\n\
             StateSaveLocation={d}/state\nSlurmdSpoolDir={d}/spool\n\
             SlurmctldPidFile={d}/slurmctld.pid\nSlurmdPidFile={d}/slurmd.pid\n\
             SlurmctldLogFile={d}/slurmctld.log\nSlurmdLogFile={d}/slurmd.log\n\
             ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n\
             JobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n\
             SchedulerType=sched/builtin\nSelectType=select/cons_tres\nSelectTypeParameters=CR_CPU\n\
             MpiDefault=none\nReturnToService=2\nMinJobAge=600\n\
             NodeName=localhost NodeAddr=127.0.0.1 CPUs=2 RealMemory={mem_mb} State=UNKNOWN\n\
             PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP\n"
        );
        std::fs::write(&conf, text).map_err(|e| (None, e.to_string()))?;
        let mut c = Cluster {
            dir: dir.to_path_buf(),
            conf: conf.clone(),
            daemons: Vec::new(),
        };
        let s = |p: &Path| p.display().to_string();
        let munged = [
            "--foreground".to_string(),
            "--force".into(),
            format!("--socket={}", s(&socket)),
            format!("--key-file={}", s(&key)),
            format!("--pid-file={}", s(&dir.join("munged.pid"))),
            format!("--log-file={}", s(&dir.join("munged.log"))),
            format!("--seed-file={}", s(&dir.join("munged.seed"))),
        ];
        let started = (|| -> Result<(), String> {
            c.spawn(
                "munged",
                &munged.iter().map(String::as_str).collect::<Vec<_>>(),
            )?;
            let t = Instant::now();
            while !socket.exists() {
                if t.elapsed() > Duration::from_secs(10) {
                    return Err("munged made no socket in 10 s".into());
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let conf = s(&conf);
            c.spawn("slurmctld", &["-D", "-c", "-f", &conf])?;
            c.spawn("slurmd", &["-D", "-f", &conf, "-N", "localhost"])?;
            let t = Instant::now();
            loop {
                let state = c.ask("sinfo", &["-h", "-o", "%T"]);
                if state.trim() == "idle" {
                    return Ok(());
                }
                for (name, child) in &mut c.daemons {
                    if let Ok(Some(status)) = child.try_wait() {
                        return Err(format!("{name} ended: {status}"));
                    }
                }
                if t.elapsed() > Duration::from_secs(30) {
                    return Err(format!(
                        "the node is not idle after 30 s (sinfo: {state:?})"
                    ));
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        })();
        match started {
            Ok(()) => Ok(c),
            Err(e) => {
                let logs = c.logs();
                Err((Some(c), format!("{e}\n{logs}")))
            }
        }
    }

    /// Waits until no job is queued or running; false after `timeout`.
    fn wait_idle(&self, timeout: Duration) -> bool {
        let t = Instant::now();
        while t.elapsed() < timeout {
            let out = self.command("squeue").args(["-h", "-o", "%i %T"]).output();
            if let Ok(o) = out {
                if o.status.success() && o.stdout.iter().all(u8::is_ascii_whitespace) {
                    return true;
                }
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        false
    }
}

impl Drop for Cluster {
    /// Cancels every job, lets their steps end, then stops slurmd, slurmctld and munged
    /// (the children this cluster started, by their ids: SIGTERM, then SIGKILL) and reaps
    /// them.
    fn drop(&mut self) {
        if self.daemons.iter().any(|(n, _)| *n == "slurmctld") {
            let _ = self
                .command("scancel")
                .args(["--full", "--partition=debug"])
                .output();
            self.wait_idle(Duration::from_secs(20));
        }
        for (_, child) in self.daemons.iter_mut().rev() {
            // SIGTERM first (slurmctld stops its slurmscriptd), SIGKILL after 10 s.
            let _ = Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status();
            let t = Instant::now();
            while matches!(child.try_wait(), Ok(None)) && t.elapsed() < Duration::from_secs(10) {
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// The corpus: two pieces of a few seconds on the small layout's keys.
fn pieces(dir: &Path) -> PathBuf {
    let c = dir.join("corpus");
    std::fs::create_dir_all(&c).unwrap();
    for (name, base) in [("one", 60u8), ("two", 62)] {
        let notes: Vec<(u8, u8, f64, f64)> = (0..10)
            .map(|j| {
                let t = 0.2 + 0.25 * j as f64;
                (base + (j % 4) as u8, 30 + (j * 9 % 90) as u8, t, t + 0.15)
            })
            .collect();
        write_midi(&c.join(format!("{name}.mid")), &notes, &[]);
    }
    c
}

/// The example job array over two short pieces on a real one-node Slurm cluster: each task
/// plays its shard on the emulated board, the merge job the first task submits writes the
/// tables, and they are one machine's; every daemon is gone afterwards.
#[test]
fn the_example_job_array_on_slurm_merges_into_the_single_machine_tables() {
    let missing: Vec<&str> = [
        "munged",
        "slurmctld",
        "slurmd",
        "sbatch",
        "squeue",
        "sinfo",
        "scancel",
    ]
    .into_iter()
    .filter(|t| tool(t).is_none())
    .collect();
    if !missing.is_empty() {
        let _ = skip(&format!(
            "{} not installed (Debian: apt-get install slurm-wlm munge)",
            missing.join(", ")
        ));
        return;
    }
    // A short path: munged's socket must fit a Unix socket's 108 bytes.
    let dir = temp_dir("slurm");
    let cluster = match Cluster::start(&dir) {
        Ok(c) => c,
        Err((c, why)) => {
            drop(c);
            let _ = skip(&format!("Slurm did not start: {why}"));
            return;
        }
    };
    let pids: Vec<u32> = cluster.daemons.iter().map(|(_, c)| c.id()).collect();
    let corpus = pieces(&dir);
    let layout = small_layout(&dir, 60, 67);
    let out = dir.join("out");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/slurm/corpus.sbatch");
    let play_options = ["--layout", layout.to_str().unwrap(), "--seconds", "2.5"];
    let submitted = cluster
        .command("sbatch")
        .args(["--parsable", "--array=0-1", "--cpus-per-task=1"])
        .arg(format!("--chdir={}", dir.display()))
        .arg(format!("--output={}/task-%A_%a.out", dir.display()))
        .arg(&script)
        .arg(&corpus)
        .arg(&out)
        .args(play_options)
        .env("TACTUS", env!("CARGO_BIN_EXE_tactus"))
        .output()
        .unwrap();
    assert_ok(&submitted);
    let finished = cluster.wait_idle(Duration::from_secs(300));
    let logs = || {
        let mut s = cluster.logs();
        for f in std::fs::read_dir(&dir)
            .unwrap()
            .chain(std::fs::read_dir(&out).unwrap())
            .flatten()
        {
            let n = f.file_name().to_string_lossy().into_owned();
            if n.ends_with(".out") && (n.starts_with("task-") || n.starts_with("merge-")) {
                s.push_str(&format!(
                    "\n--- {n}:\n{}",
                    std::fs::read_to_string(f.path()).unwrap_or_default()
                ));
            }
        }
        s
    };
    assert!(finished, "the jobs did not end in 300 s\n{}", logs());
    for k in 1..=2 {
        assert!(
            out.join(format!("results-{k}-of-2.jsonl")).exists(),
            "task {k}'s results\n{}",
            logs()
        );
    }
    assert!(
        out.join("corpus.csv").exists(),
        "the merge's tables\n{}",
        logs()
    );
    let merge_log: String = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter(|f| f.file_name().to_string_lossy().starts_with("merge-"))
        .filter(|f| f.file_name().to_string_lossy().ends_with(".out"))
        .map(|f| std::fs::read_to_string(f.path()).unwrap_or_default())
        .collect();
    assert!(
        merge_log.contains("merged 2 shards"),
        "{merge_log}\n{}",
        logs()
    );
    // One machine, the same corpus and options.
    let single = dir.join("single");
    let one = tactus()
        .args(["play", "--no-wav", "--out"])
        .arg(&single)
        .arg(&corpus)
        .args(play_options)
        .output()
        .unwrap();
    assert_ok(&one);
    for t in ["corpus.csv", "corpus.json"] {
        assert_eq!(
            without_timings(&out.join(t)),
            without_timings(&single.join(t)),
            "{t}"
        );
    }
    let rows = std::fs::read_to_string(single.join("corpus.csv")).unwrap();
    assert_eq!(rows.lines().count(), 3, "{rows}");
    // The daemons are gone once the cluster is dropped.
    drop(cluster);
    for pid in pids {
        let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
        assert!(
            status.is_empty() || status.contains("State:\tZ"),
            "process {pid} still runs: {status}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
