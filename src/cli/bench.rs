//! `volcast bench accuracy` and `volcast bench speed`: run the benches, print their
//! summaries, write their files.

use std::process::ExitCode;

use volcast::bench;

use super::args::{AccuracyArgs, SpeedArgs};
use super::render::with_threads;

/// Runs the accuracy bench.
pub fn accuracy(a: AccuracyArgs) -> anyhow::Result<ExitCode> {
    let opts = bench::Options::new(a.quick);
    let mut command = String::from("volcast bench accuracy");
    if a.quick {
        command += " --quick";
    }
    command += &format!(" --out {}", a.out.display());
    if let Some(t) = a.threads {
        command += &format!(" --threads {t}");
    }

    bench::check_writable(&a.out, &["images"])?;
    let report = with_threads(a.threads.map(usize::from), || {
        let mut last = usize::MAX;
        bench::accuracy(&opts, &command, &mut |done, total| {
            let pct = 100 * done / total.max(1);
            if pct / 10 != last / 10 || done == total {
                eprintln!("bench: {done}/{total} cases");
                last = pct;
            }
        })
    })??;
    println!("{}", report.summary());
    for f in report.write(&a.out)? {
        eprintln!("wrote {}", f.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// Runs the speed bench.
pub fn speed(a: SpeedArgs) -> anyhow::Result<ExitCode> {
    let mut opts = bench::SpeedOptions::new(a.quick, a.threads.map(usize::from));
    let mut command = String::from("volcast bench speed");
    if a.quick {
        command += " --quick";
    }
    if let Some(r) = a.repeats {
        opts.repeats = usize::from(r);
        command += &format!(" --repeats {r}");
    }
    if let Some(t) = a.threads {
        command += &format!(" --threads {t}");
    }
    if let Some(only) = &a.only {
        opts.only = Some(only.clone());
        command += &format!(" --only {only}");
    }
    if let Some(dir) = &a.out {
        bench::check_writable(dir, &[])?;
    }
    let report = bench::speed(&opts, &command, &mut |line| eprintln!("bench: {line}"))?;
    println!("{}", report.markdown());
    if let Some(dir) = &a.out {
        for f in report.write(dir)? {
            eprintln!("wrote {}", f.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
