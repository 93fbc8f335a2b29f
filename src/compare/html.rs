//! The comparison as one self-contained HTML page ([`page`]): the table, the failed and
//! skipped trackers, and the figures of [`super::figures`] as inline SVG (no file beside it,
//! no script, no network).

use super::{figures, table, CompareReport};
use crate::eval::plot::PlotError;

/// `text` with the five HTML special characters escaped.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A figure: its inline SVG, or a line saying why it is missing.
fn figure(title: &str, svg: Result<String, PlotError>, caption: &str) -> String {
    let body = match svg {
        Ok(svg) => svg,
        Err(e) => format!("<p><em>not drawn: {}</em></p>", escape(&e.to_string())),
    };
    format!(
        "<h2>{}</h2>\n<figure>{body}<figcaption>{}</figcaption></figure>\n",
        escape(title),
        escape(caption)
    )
}

/// The table of [`table::table`] as an HTML table, with a coloured swatch per tracker (the
/// colours of the figures).
fn html_table(report: &CompareReport) -> String {
    let mut rows = String::from("<tr>");
    for c in table::COLUMNS {
        rows.push_str(&format!("<th>{}</th>", escape(c)));
    }
    rows.push_str("</tr>\n");
    for (i, t) in report.trackers.iter().enumerate() {
        let Some(run) = &t.run else { continue };
        let colour = figures::colour(i);
        rows.push_str(&format!(
            "<tr><td><span style=\"color:rgb({},{},{})\">&#9632;</span> ",
            colour.0, colour.1, colour.2
        ));
        let cells = table::cells(t, run);
        rows.push_str(
            &cells
                .iter()
                .map(|c| escape(c))
                .collect::<Vec<_>>()
                .join("</td><td>"),
        );
        rows.push_str("</td></tr>\n");
    }
    let notes: Vec<String> = table::notes(report)
        .iter()
        .map(|l| format!("<li>{}</li>", escape(l)))
        .collect();
    let notes = if notes.is_empty() {
        String::new()
    } else {
        format!("<ul>{}</ul>\n", notes.join(""))
    };
    format!("<table>\n{rows}</table>\n{notes}")
}

/// The page: heading (dataset, format, frames, camera), the table, the trajectories, the
/// per-frame error and the inliers beside the photometric residual.
pub fn page(report: &CompareReport) -> String {
    let mut body = format!(
        "<h1>vofront compare</h1>\n<p>{}</p>\n{}",
        escape(&report.headline()),
        html_table(report)
    );
    body.push_str(
        "<p>ATE: RMSE after alignment (sim3 for trackers whose scale is arbitrary, se3 for \
         metric ones); % path: over the ground-truth path length; RPE: consecutive frames, \
         translation (m) / rotation (deg) RMSE; breaks: restarts at a guess after a failure; \
         lost at: frame indices without a pose.</p>\n",
    );
    body.push_str(&figure(
        "Trajectories",
        figures::trajectories(report),
        "Top view (x right, z up the page) of the ground truth (black) and each tracker after \
         its alignment.",
    ));
    body.push_str(&figure(
        "Error per frame",
        figures::errors(report),
        "Distance of each posed frame from the ground truth after the tracker's alignment; \
         gaps are frames without a pose.",
    ));
    body.push_str(&figure(
        "Inliers and photometric residual",
        figures::support(report),
        "Left: inlier correspondences of the feature trackers. Right: photometric residual \
         RMSE of the direct trackers.",
    ));
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>vofront compare: {}</title>\n<style>\n\
         body {{ font-family: sans-serif; margin: 2em; }}\n\
         table {{ border-collapse: collapse; }}\n\
         th, td {{ border: 1px solid #ccc; padding: 0.3em 0.6em; text-align: right; }}\n\
         th:first-child, td:first-child {{ text-align: left; }}\n\
         figure {{ margin: 0; }} svg {{ max-width: 100%; height: auto; }}\n\
         </style>\n</head>\n<body>\n{body}</body>\n</html>\n",
        escape(&report.dataset)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_replaces_the_special_characters() {
        assert_eq!(
            escape("a<b & \"c\" 'd'>"),
            "a&lt;b &amp; &quot;c&quot; &#39;d&#39;&gt;"
        );
    }
}
