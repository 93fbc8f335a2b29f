//! The comparison as a text table, one line per tracker ([`table`]).

use super::{CompareReport, TrackerResult, TrackerRun};
use crate::report::Entry;

/// The columns of [`table`].
pub const COLUMNS: [&str; 9] = [
    "method",
    "ATE rmse",
    "% path",
    "RPE m / deg",
    "posed/frames",
    "lost",
    "breaks",
    "ms mean/median",
    "lost at",
];

/// `x` with `digits` decimals, `-` when absent.
fn num(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "-".into(), |x| format!("{x:.digits$}"))
}

/// The cells of one tracker's line (in the order of [`COLUMNS`]).
pub(super) fn cells(t: &TrackerResult, run: &TrackerRun) -> Vec<String> {
    let ate = match &run.ate {
        Some(Entry::Ok(a)) => format!("{:.4} m ({})", a.stats.rmse, t.alignment),
        Some(Entry::Failed { .. }) => "n/a".into(),
        None => "-".into(),
    };
    let rpe = match &run.rpe {
        Some(Entry::Ok(r)) => format!("{:.4} / {:.3}", r.translation.rmse, r.rotation_deg.rmse),
        Some(Entry::Failed { .. }) => "n/a".into(),
        None => "-".into(),
    };
    let spans: Vec<String> = run
        .lost_spans
        .iter()
        .map(|[a, b]| {
            if a == b {
                format!("{a}")
            } else {
                format!("{a}-{b}")
            }
        })
        .collect();
    vec![
        t.method.name().to_string(),
        ate,
        num(run.ate_percent, 2),
        rpe,
        format!("{}/{}", run.posed, run.frames),
        run.lost.to_string(),
        run.segment_breaks.to_string(),
        format!("{}/{}", num(run.ms_mean, 1), num(run.ms_median, 1)),
        if spans.is_empty() {
            "-".into()
        } else {
            spans.join(",")
        },
    ]
}

/// One line per tracker that failed (with its error) and per tracker skipped (with why).
pub fn notes(report: &CompareReport) -> Vec<String> {
    let failed = report
        .trackers
        .iter()
        .filter(|t| t.run.is_none())
        .map(|t| match &t.error {
            Some(e) => format!("{}: failed: {e}", t.method.name()),
            None => format!("{}: did not run", t.method.name()),
        });
    let skipped = report
        .skipped
        .iter()
        .map(|s| format!("{}: skipped: {}", s.method, s.reason));
    failed.chain(skipped).collect()
}

/// The report as text: a header line naming the dataset, a table of the trackers that ran
/// ([`COLUMNS`]), then one line per tracker that failed and per tracker skipped.
pub fn table(report: &CompareReport) -> String {
    let mut rows: Vec<Vec<String>> = vec![COLUMNS.iter().map(|c| c.to_string()).collect()];
    rows.extend(
        report
            .trackers
            .iter()
            .filter_map(|t| t.run.as_ref().map(|run| cells(t, run))),
    );
    let widths: Vec<usize> = (0..COLUMNS.len())
        .map(|c| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0))
        .collect();
    let mut out = format!("{}\n", report.headline());
    for row in &rows {
        let line: Vec<String> = row
            .iter()
            .zip(&widths)
            .map(|(cell, &w)| format!("{cell:<w$}"))
            .collect();
        out.push_str(line.join("  ").trim_end());
        out.push('\n');
    }
    for note in notes(report) {
        out.push_str(&note);
        out.push('\n');
    }
    out.push_str(&format!(
        "total {:.1} s{}\n",
        report.wall_ms / 1e3,
        if report.interrupted {
            " (interrupted)"
        } else {
            ""
        }
    ));
    out
}
