//! `volcast check`: validate a scene and print its plan, reading only the volume's header.

use std::process::ExitCode;

use volcast::plan::Plan;

use super::args::CheckArgs;

pub fn run(a: CheckArgs) -> anyhow::Result<ExitCode> {
    let (scene, opts, limits) = super::render::prepare(&a.scene)?;
    let header = scene.volume.source.header()?;
    let plan = Plan::build(&scene, &header, &opts)?;
    limits.check(&header.sizes, header.scalar_type.size())?;
    println!("{}", plan.describe(&scene, &header));
    for w in &scene.warnings {
        println!("warning  {w}");
    }
    println!("ok");
    Ok(ExitCode::SUCCESS)
}
