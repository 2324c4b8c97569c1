//! `etp run`: run a strategy as processes ([`etp_launcher`]) and
//! print the report; `--plot` draws it.

use crate::run_args::RunArgs;
use anyhow::Result;
use etp_launcher::{RecordTo, RunRequest, exit_for, figure, problems, report};
use std::path::PathBuf;

/// Where `--plot` writes (`{run}` = the run id, known once the run starts).
fn plot_stem(a: &RunRequest, out: Option<&PathBuf>) -> PathBuf {
    if let Some(stem) = out {
        return stem.clone();
    }
    match (&a.record, &a.run_id) {
        (RecordTo::File(r), _) => r.with_extension("").with_file_name(format!(
            "{}-report",
            r.file_stem().and_then(|x| x.to_str()).unwrap_or("run")
        )),
        (_, Some(id)) => PathBuf::from(format!("run-{id}-report")),
        (_, None) => PathBuf::from("run-{run}-report"),
    }
}

/// Run, print the report; the exit code is 0 only for a clean run, else
/// [`etp_launcher::EXIT_INTERRUPTED`], [`etp_launcher::EXIT_ACCOUNTING`]
/// or [`etp_launcher::EXIT_DEGRADED`] (the report and stderr say why).
pub fn run(args: RunArgs) -> Result<()> {
    let a = args.request()?;
    let stem = args.plot.then(|| plot_stem(&a, args.plot_out.as_ref()));
    if let Some(stem) = &stem {
        etp_files::write::existing_folder_of(stem, "-o")?;
        for p in [stem.with_extension("png"), stem.with_extension("svg")] {
            etp_files::write::refuse_existing(&p, a.force)?;
        }
    }
    let (plan, outcome) = etp_launcher::execute_run(&a)?;
    report::print(&a, &plan, &outcome)?;
    if let Some(stem) = &stem {
        let stem = stem
            .to_string_lossy()
            .replace("{run}", plan.run_id.as_str());
        let stem = std::path::Path::new(&stem);
        etp_figures::report_plot(&figure::figure(&plan, &outcome), stem)?;
        eprintln!("wrote {} and .svg", stem.with_extension("png").display());
    }
    Ok(exit_for(&problems(&a, &outcome))?)
}
