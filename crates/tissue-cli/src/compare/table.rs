//! Table 1, measured: Markdown and HTML, criteria as rows and kinds as columns; each cell the
//! measured values, our score and the survey's.

use tissue::compare::CompareRecord;
use tissue::compare::survey::{CRITERIA, GROUPS};

fn num(x: f64) -> String {
    let s = format!("{x:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn survey(x: Option<f64>) -> String {
    x.map_or("—".into(), num)
}

fn md_escape(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

/// The Markdown table: a header per kind, per criterion row "score (survey) — measured".
pub fn markdown(r: &CompareRecord) -> String {
    let mut s = String::new();
    s.push_str("# Table 1, measured\n\n");
    s.push_str(&format!(
        "Organ: {} · {} · `{}` · tissue {}\n\n",
        r.organ,
        if r.settings.quick { "quick" } else { "full" },
        r.command,
        r.version
    ));
    s.push_str("Each cell: **our score** (the survey's score for the kind's column) — the measured values. ");
    s.push_str(
        "Scores run from 0 to the criterion's weight; the rules are in `docs/compare.md`.\n\n",
    );
    let levels: Vec<String> = r
        .reference
        .levels
        .iter()
        .map(|l| {
            format!(
                "{} tets: {:.4e} N, {} contacts",
                l.tets, l.probe_force, l.contacts
            )
        })
        .collect();
    s.push_str(&format!(
        "Reference: {} ({}); change between the two finest levels {:.2} %.\n\n",
        r.reference.model,
        levels.join(", "),
        100.0 * r.reference.convergence
    ));
    // Summary table: totals.
    s.push_str("| kind | survey column | ");
    s.push_str(&GROUPS.map(|g| format!("{g} (15)")).join(" | "));
    s.push_str(" | Total (45) |\n|---|---|---|---|---|---|\n");
    for (k, sc) in r.kinds.iter().zip(&r.scores) {
        let g = |i: usize| {
            format!(
                "**{}** ({})",
                num(sc.groups[i]),
                survey(sc.survey_groups.map(|x| x[i]))
            )
        };
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | **{}** ({}) |\n",
            k.kind,
            k.column,
            g(0),
            g(1),
            g(2),
            num(sc.total),
            survey(sc.survey_total)
        ));
    }
    s.push('\n');
    // Per criterion: a section with one row per kind (13 × 15 cells do not fit a page).
    for (g, group) in GROUPS.iter().enumerate() {
        s.push_str(&format!("## {group}\n\n"));
        for (i, c) in CRITERIA.iter().enumerate().filter(|(_, c)| c.group == g) {
            s.push_str(&format!("### {} (weight {})\n\n", c.name, num(c.weight)));
            s.push_str("| kind | score | survey | measured |\n|---|---|---|---|\n");
            for sc in &r.scores {
                let cell = &sc.cells[i];
                s.push_str(&format!(
                    "| {} | **{}** | {} | {} |\n",
                    sc.kind,
                    num(cell.score),
                    survey(cell.survey),
                    md_escape(&cell.shown)
                ));
            }
            s.push('\n');
        }
    }
    s
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The HTML table: criteria as rows, kinds as columns, as in the survey.
pub fn html(r: &CompareRecord) -> String {
    let mut s = String::from(
        "<!doctype html><meta charset=\"utf-8\"><title>Table 1, measured</title>\n<style>\
         body{font-family:sans-serif;font-size:12px}table{border-collapse:collapse}\
         td,th{border:1px solid #ccc;padding:3px;vertical-align:top}\
         .s{font-weight:bold;font-size:14px}.v{color:#555;font-size:10px}.g{background:#eef}\
         </style>\n",
    );
    s.push_str(&format!(
        "<h1>Table 1, measured</h1><p>Organ: {} · {} · <code>{}</code> · tissue {}. Each cell: \
         our score (survey's score) and the measured values. Rules: docs/compare.md.</p>\n",
        esc(&r.organ),
        if r.settings.quick { "quick" } else { "full" },
        esc(&r.command),
        esc(&r.version)
    ));
    s.push_str("<table><tr><th>criterion</th><th>weight</th>");
    for k in &r.kinds {
        s.push_str(&format!(
            "<th>{}<br><span class=v>{}</span></th>",
            esc(&k.kind),
            esc(&k.column)
        ));
    }
    s.push_str("</tr>\n");
    for (g, group) in GROUPS.iter().enumerate() {
        s.push_str(&format!(
            "<tr class=g><th colspan={}>{}</th></tr>\n",
            r.kinds.len() + 2,
            group
        ));
        for (i, c) in CRITERIA.iter().enumerate().filter(|(_, c)| c.group == g) {
            s.push_str(&format!(
                "<tr><td>{}</td><td>{}</td>",
                esc(c.name),
                num(c.weight)
            ));
            for sc in &r.scores {
                let cell = &sc.cells[i];
                s.push_str(&format!(
                    "<td><span class=s>{}</span> ({})<br><span class=v>{}</span></td>",
                    num(cell.score),
                    survey(cell.survey),
                    esc(&cell.shown)
                ));
            }
            s.push_str("</tr>\n");
        }
        s.push_str("<tr class=g><td>Total</td><td>15</td>");
        for sc in &r.scores {
            s.push_str(&format!(
                "<td><span class=s>{}</span> ({})</td>",
                num(sc.groups[g]),
                survey(sc.survey_groups.map(|x| x[g]))
            ));
        }
        s.push_str("</tr>\n");
    }
    s.push_str("<tr class=g><th>Total</th><th>45</th>");
    for sc in &r.scores {
        s.push_str(&format!(
            "<th>{} ({})</th>",
            num(sc.total),
            survey(sc.survey_total)
        ));
    }
    s.push_str("</tr></table>\n");
    s
}

/// The totals, for the terminal.
pub fn summary(r: &CompareRecord) -> String {
    let mut s = format!(
        "{:<26} {:>8} {:>8} {:>8} {:>8}   (survey's total)\n",
        "kind", "comp.", "topol.", "realism", "total"
    );
    for sc in &r.scores {
        s.push_str(&format!(
            "{:<26} {:>8.2} {:>8.2} {:>8.2} {:>8.2}   {}\n",
            sc.kind,
            sc.groups[0],
            sc.groups[1],
            sc.groups[2],
            sc.total,
            survey(sc.survey_total)
        ));
    }
    s
}
