//! `volcast check`: validate a scene and print its plan, reading only the volume's header.

use std::process::ExitCode;

use anyhow::Context;
use volcast::plan::Plan;

use super::args::CheckArgs;

pub fn run(a: CheckArgs) -> anyhow::Result<ExitCode> {
    let (scene, opts, limits) = super::render::prepare(&a.scene)?;
    let context = || format!("checking {}", scene.path.display());
    let _scope = volcast::pipeline::confine_run(&scene, &opts).with_context(context)?;
    let headers = volcast::pipeline::headers(&scene).with_context(context)?;
    let plan = Plan::build(&scene, &headers, &opts)?;
    plan.check_memory(&limits)?;
    let mut text = plan.describe(&scene);
    text.push('\n');
    if opts.resume {
        let total = plan.frame_list.len() * scene.passes.len();
        text += &match volcast::pipeline::completed_images(&plan)
            .with_context(context)?
        {
            Some(done) => format!(
                "resume   {done} of {total} images of these frames are complete and will be skipped\n"
            ),
            None => format!(
                "resume   the volume's files are not those the output folder's manifest recorded (or it recorded none): render --resume hashes the voxels to tell which of the {total} images are still valid\n"
            ),
        };
    }
    for w in &scene.warnings {
        text += &format!("warning  {w}\n");
    }
    text += "ok\n";
    super::print(&text).context("printing the plan")?;
    Ok(ExitCode::SUCCESS)
}
