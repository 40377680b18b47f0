//! The long fuzz run: seeded mutations of the NRRD, NIfTI and MetaImage fixtures
//! (through `volcast info`) and of the example scenes (through `volcast check`), every case its own process
//! under a timeout, its peak resident memory measured (no address-space limit, which
//! would turn a blow-up into a clean allocation failure and hide it), so that hangs,
//! aborts and memory blow-ups are caught, not only panics.
//!
//! ```text
//! cargo build --release
//! cargo run --release --example fuzz -- [--kind nrrd|formats|scene|both|all] [--cases N] [--seed S]
//!     [--jobs J] [--timeout SECONDS] [--max-rss BYTES] [--volcast PATH] [--out DIR]
//!     [--dump CASE]
//! ```
//!
//! Defaults: all three kinds (`both` is nrrd and scene), 100000 cases each, seed 1, one job per core, 10 s, a peak
//! resident memory of 512 MiB per case (with `--max-memory 256M` for volcast itself), the release
//! binary beside this example, failures saved in `fuzz-failures/`. A case fails if
//! volcast is killed by a signal (an abort, a crash), runs past the timeout, exits
//! with a status other than 0 or 1 (101 is a panic, 2 a usage error), reports an
//! internal error or running out of memory, or its peak resident memory (`ru_maxrss`
//! of the child, from `wait4`) passes the bound; a case whose resident memory passes
//! the bound while it runs is stopped then. The summary of each kind gives the
//! largest, the 99th percentile and the median peak resident memory of its cases. Case `i` of a kind and seed is always the
//! same input, so a failure is reproduced from the three numbers (`--dump CASE`
//! writes that input to standard output).

#[path = "../tests/fuzz/mutate.rs"]
mod mutate;

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use mutate::{case, corpus, Kind};

struct Options {
    /// Write case N of the first kind to standard output instead of running.
    dump: Option<u64>,
    kinds: Vec<Kind>,
    cases: u64,
    seed: u64,
    jobs: usize,
    timeout: Duration,
    max_rss: u64,
    volcast: PathBuf,
    out: PathBuf,
}

fn usage() -> String {
    "usage: fuzz [--kind nrrd|formats|scene|both|all] [--cases N] [--seed S] [--jobs J] [--timeout SECONDS] [--max-rss BYTES] [--volcast PATH] [--out DIR] [--dump CASE]".into()
}

fn options() -> Result<Options, String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    // target/release/examples/fuzz -> target/release/volcast
    let default_volcast = exe
        .parent()
        .and_then(Path::parent)
        .map(|d| d.join("volcast"))
        .unwrap_or_else(|| PathBuf::from("volcast"));
    let mut o = Options {
        dump: None,
        kinds: vec![Kind::Nrrd, Kind::Formats, Kind::Scene],
        cases: 100_000,
        seed: 1,
        jobs: std::thread::available_parallelism().map_or(1, |n| n.get()),
        timeout: Duration::from_secs(10),
        max_rss: 512 << 20,
        volcast: default_volcast,
        out: PathBuf::from("fuzz-failures"),
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || {
            args.next()
                .ok_or_else(|| format!("{a} needs a value\n{}", usage()))
        };
        let num = |v: String| {
            v.parse::<u64>()
                .map_err(|_| format!("{a}: not a number: {v}"))
        };
        match a.as_str() {
            "--kind" => {
                o.kinds = match value()?.as_str() {
                    "nrrd" => vec![Kind::Nrrd],
                    "scene" => vec![Kind::Scene],
                    "formats" => vec![Kind::Formats],
                    "both" => vec![Kind::Nrrd, Kind::Scene],
                    "all" => vec![Kind::Nrrd, Kind::Formats, Kind::Scene],
                    other => {
                        return Err(format!("--kind {other}: nrrd, formats, scene, both or all"))
                    }
                }
            }
            "--cases" => o.cases = num(value()?)?,
            "--seed" => o.seed = num(value()?)?,
            "--jobs" => o.jobs = num(value()?)?.max(1) as usize,
            "--timeout" => o.timeout = Duration::from_secs(num(value()?)?.max(1)),
            "--max-rss" => o.max_rss = num(value()?)?,
            "--volcast" => o.volcast = PathBuf::from(value()?),
            "--out" => o.out = PathBuf::from(value()?),
            "--dump" => o.dump = Some(num(value()?)?),
            "-h" | "--help" => return Err(usage()),
            other => return Err(format!("unknown argument {other}\n{}", usage())),
        }
    }
    if !o.volcast.is_file() && o.dump.is_none() {
        return Err(format!(
            "{} not found: run `cargo build --release` first, or pass --volcast PATH",
            o.volcast.display()
        ));
    }
    Ok(o)
}

/// How one case ended.
enum Outcome {
    /// Exit status 0 or 1 with a sensible message.
    Fine,
    /// Anything else: why.
    Failed(String),
}

/// The resident memory of a running process in bytes, from `/proc/PID/statm`.
#[cfg(target_os = "linux")]
fn resident(pid: u32) -> Option<u64> {
    let statm = std::fs::read_to_string(format!("/proc/{pid}/statm")).ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    // SAFETY: sysconf has no preconditions.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    Some(pages * page.max(1) as u64)
}

#[cfg(not(target_os = "linux"))]
fn resident(_pid: u32) -> Option<u64> {
    None
}

/// Waits for `child` (killed past `timeout`, or when its resident memory passes
/// `max_rss`); returns its wait status (`None` when it was killed for either) and
/// its peak resident memory in bytes.
#[cfg(unix)]
fn wait_measured(
    child: &mut std::process::Child,
    timeout: Duration,
    max_rss: u64,
) -> Result<(Option<i32>, u64, Option<String>), String> {
    let pid = child.id() as libc::pid_t;
    let start = Instant::now();
    let reap = |flags| {
        let mut status = 0;
        // SAFETY: a zeroed rusage is valid; wait4 reaps our own child, which std
        // never waits for afterwards.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        let r = unsafe { libc::wait4(pid, &mut status, flags, &mut usage) };
        (r, status, usage.ru_maxrss as u64 * 1024)
    };
    loop {
        let (r, status, peak) = reap(libc::WNOHANG);
        if r == pid {
            return Ok((Some(status), peak, None));
        }
        if r < 0 {
            return Err(format!(
                "waiting for volcast: {}",
                std::io::Error::last_os_error()
            ));
        }
        let why = if start.elapsed() > timeout {
            Some(format!("hang: still running after {timeout:?}"))
        } else {
            resident(child.id())
                .filter(|&rss| rss > max_rss)
                .map(|rss| {
                    format!(
                        "memory: {} MiB resident while running, above the bound of {} MiB",
                        rss >> 20,
                        max_rss >> 20
                    )
                })
        };
        if let Some(why) = why {
            let _ = child.kill();
            let (_, _, peak) = reap(0);
            return Ok((None, peak, Some(why)));
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Runs volcast on one case file in `dir`; returns how it ended and its peak
/// resident memory in bytes (0 where it cannot be measured).
fn run_case(o: &Options, kind: Kind, dir: &Path, name: &str) -> (Outcome, u64) {
    let mut cmd = Command::new(&o.volcast);
    match kind {
        Kind::Nrrd | Kind::Formats => cmd.args(["info", name, "--max-memory", "256M"]),
        Kind::Scene => cmd.args(["check", name, "--max-memory", "256M", "--out", "out"]),
    };
    cmd.current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        let cpu = o.timeout.as_secs() as libc::rlim_t + 5;
        // SAFETY: setrlimit is async-signal-safe; the closure touches nothing else.
        unsafe {
            cmd.pre_exec(move || {
                let cpu = libc::rlimit {
                    rlim_cur: cpu,
                    rlim_max: cpu,
                };
                if libc::setrlimit(libc::RLIMIT_CPU, &cpu) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
    }
    let mut child = match cmd.spawn() {
        Ok(c) => c,
        Err(e) => return (Outcome::Failed(format!("could not start volcast: {e}")), 0),
    };
    let mut stderr = child.stderr.take();
    let reader = std::thread::spawn(move || {
        let mut s = Vec::new();
        if let Some(e) = stderr.as_mut() {
            let _ = e.take(1 << 20).read_to_end(&mut s);
        }
        s
    });
    #[cfg(unix)]
    let waited = wait_measured(&mut child, o.timeout, o.max_rss);
    #[cfg(not(unix))]
    let waited: Result<(Option<i32>, u64, Option<String>), String> = {
        let start = Instant::now();
        loop {
            match child.try_wait() {
                Ok(Some(s)) => break Ok((s.code(), 0, None)),
                Ok(None) if start.elapsed() > o.timeout => {
                    let _ = child.kill();
                    let _ = child.wait();
                    break Ok((
                        None,
                        0,
                        Some(format!("hang: still running after {:?}", o.timeout)),
                    ));
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(2)),
                Err(e) => break Err(format!("waiting for volcast: {e}")),
            }
        }
    };
    let err = String::from_utf8_lossy(&reader.join().unwrap_or_default()).into_owned();
    let (status, peak, killed) = match waited {
        Ok(w) => w,
        Err(why) => return (Outcome::Failed(why), 0),
    };
    if let Some(why) = killed {
        return (Outcome::Failed(format!("{why}: {err}")), peak);
    }
    if peak > o.max_rss {
        return (
            Outcome::Failed(format!(
                "memory: a peak resident memory of {} MiB, above the bound of {} MiB: {err}",
                peak >> 20,
                o.max_rss >> 20
            )),
            peak,
        );
    }
    (judge(status, &err), peak)
}

/// The outcome of a finished case from its wait status (unix) or exit code.
fn judge(status: Option<i32>, err: &str) -> Outcome {
    #[cfg(unix)]
    let (code, signal) = match status {
        Some(s) if libc::WIFEXITED(s) => (Some(libc::WEXITSTATUS(s)), None),
        Some(s) if libc::WIFSIGNALED(s) => (None, Some(libc::WTERMSIG(s))),
        _ => (None, None),
    };
    #[cfg(not(unix))]
    let (code, signal): (Option<i32>, Option<i32>) = (status, None);
    match code {
        Some(0) => Outcome::Fine,
        Some(1) if err.contains("internal error") => Outcome::Failed(format!("panic: {err}")),
        Some(1) if err.contains("out of memory") => {
            Outcome::Failed(format!("memory over the limit: {err}"))
        }
        Some(1) if err.starts_with("volcast: error: ") => Outcome::Fine,
        Some(1) => Outcome::Failed(format!("status 1 without a message: {err}")),
        Some(c) => Outcome::Failed(format!("exit status {c}: {err}")),
        None => Outcome::Failed(format!("killed by signal {signal:?}: {err}")),
    }
}

/// Copies the fixtures in `folder` (and their data files) into `dir`.
fn copy_fixtures(root: &Path, folder: &str, dir: &Path) -> std::io::Result<()> {
    for e in std::fs::read_dir(root.join(folder))? {
        let p = e?.path();
        if p.is_file() {
            std::fs::copy(&p, dir.join(p.file_name().unwrap_or_default()))?;
        }
    }
    Ok(())
}

fn fuzz(o: &Options, kind: Kind) -> u64 {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let seeds = corpus(kind, &root);
    let next = AtomicU64::new(0);
    let failures = AtomicU64::new(0);
    let peaks = std::sync::Mutex::new(Vec::<(u64, u64)>::new());
    let start = Instant::now();
    std::thread::scope(|s| {
        for job in 0..o.jobs {
            let (seeds, next, failures, root, peaks) = (&seeds, &next, &failures, &root, &peaks);
            s.spawn(move || {
                let dir = std::env::temp_dir().join(format!(
                    "volcast-fuzz-{}-{}-{job}",
                    std::process::id(),
                    kind.name()
                ));
                let _ = std::fs::remove_dir_all(&dir);
                std::fs::create_dir_all(&dir).expect("a temporary folder");
                if let Some(folder) = kind.fixtures() {
                    copy_fixtures(root, folder, &dir).expect("the fixtures");
                }
                mutate::prepare_dir(&dir);
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= o.cases {
                        break;
                    }
                    let (name, bytes) = case(kind, seeds, o.seed, i);
                    let Ok(path) = mutate::place(&dir, &name, &bytes) else {
                        continue;
                    };
                    let given = path.strip_prefix(&dir).unwrap_or(&path).to_string_lossy();
                    let (outcome, peak) = run_case(o, kind, &dir, &given);
                    peaks.lock().map(|mut p| p.push((peak, i))).ok();
                    if let Outcome::Failed(why) = outcome {
                        failures.fetch_add(1, Ordering::Relaxed);
                        let keep = o.out.join(format!("{}-{}-{i}", kind.name(), o.seed));
                        let _ = std::fs::create_dir_all(&keep);
                        let _ = std::fs::write(keep.join(&name), &bytes);
                        let _ = std::fs::write(keep.join("why.txt"), &why);
                        eprintln!(
                            "{} case {i}: {}",
                            kind.name(),
                            why.lines().next().unwrap_or("")
                        );
                    }
                    if (i + 1) % 5000 == 0 {
                        eprintln!(
                            "{} {}/{} cases, {} failures, {:.0} s",
                            kind.name(),
                            i + 1,
                            o.cases,
                            failures.load(Ordering::Relaxed),
                            start.elapsed().as_secs_f64()
                        );
                    }
                }
                let _ = std::fs::remove_dir_all(&dir);
            });
        }
    });
    let failed = failures.load(Ordering::Relaxed);
    let mut peaks = peaks.into_inner().unwrap_or_default();
    peaks.sort_unstable();
    let mib = |q: f64| {
        let k = ((peaks.len().max(1) - 1) as f64 * q).round() as usize;
        peaks
            .get(k)
            .map_or(0.0, |p| p.0 as f64 / f64::from(1 << 20))
    };
    println!(
        "fuzz {}: {} cases (seed {}), {failed} failures, {:.0} s; peak resident memory per case: median {:.1} MiB, 99th percentile {:.1} MiB, largest {:.1} MiB (case {}), bound {} MiB",
        kind.name(),
        o.cases,
        o.seed,
        start.elapsed().as_secs_f64(),
        mib(0.5),
        mib(0.99),
        mib(1.0),
        peaks.last().map_or(0, |p| p.1),
        o.max_rss >> 20
    );
    failed
}

fn main() -> ExitCode {
    let o = match options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    if let Some(i) = o.dump {
        use std::io::Write;
        let kind = o.kinds[0];
        let seeds = corpus(kind, Path::new(env!("CARGO_MANIFEST_DIR")));
        let (_, bytes) = case(kind, &seeds, o.seed, i);
        let _ = std::io::stdout().write_all(&bytes);
        return ExitCode::SUCCESS;
    }
    let failed: u64 = o.kinds.clone().into_iter().map(|k| fuzz(&o, k)).sum();
    if failed == 0 {
        ExitCode::SUCCESS
    } else {
        eprintln!("{failed} failing cases saved in {}", o.out.display());
        ExitCode::FAILURE
    }
}
