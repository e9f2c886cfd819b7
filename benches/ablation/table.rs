//! The ablation's Markdown table of one case (columns: module docs of `benches/ablation.rs`).

use crate::{Done, Floors};

fn fmt_ratio(v: f64, floor: f64, clean: bool) -> String {
    if clean {
        format!("{v:.4}")
    } else {
        format!("{v:.4} ({:.2}×)", v / floor)
    }
}

/// Per-material figures (albedo ratio errors, material accuracy) `v` at `prec` decimals, or
/// "–" where they are undefined: a fit with another material count than the truth's has no
/// material-by-material match (`figures` leaves them NaN).
fn fmt_matched(v: &[f64], prec: usize) -> String {
    if v.iter().any(|x| x.is_nan()) {
        return "– (K ≠ truth's)".to_string();
    }
    v.iter()
        .map(|x| format!("{x:.prec$}"))
        .collect::<Vec<_>>()
        .join(" / ")
}

pub fn table(md: &mut String, done: &[Done], fl: &Floors, clean: bool, k_true: usize) {
    md.push_str(&format!(
        "Floors: held-out (half protocol, true reflectance) {}; relit (true reflectance under the unseen maps) {:.4}; {}.\n\n",
        if crate::run_half::wanted() {
            format!("each row's own, through `run`'s judge (the common judge's {:.4})", fl.heldout)
        } else {
            format!("{:.4}", fl.heldout)
        },
        fl.relit,
        crate::true_light::describe(&fl.ratio)
    ));
    md.push_str("| light model | held-out (× photo floor) | relit, unseen maps (× MC floor) | relit vs true model | albedo ratio error R / G / B (worst) | material accuracy all / pure | K chosen (held-out RMSE per K) | train rel. | its | s |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for d in done {
        let f = &d.figures;
        let k = d.k.as_ref().map_or("–".to_string(), |(k, s)| {
            format!(
                "{}{} ({})",
                k,
                if *k == k_true { " ✓" } else { " ✗" },
                s.iter()
                    .map(|(k, e)| format!("{k}: {e:.4}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        });
        md.push_str(&format!(
            "| {} | {} | {} | {:.4} | {} | {} | {k} | {:.4} | {} | {:.0} |\n",
            d.label,
            // Noise-free, the half judge's floor is not 0 (a half fit cannot see the other half):
            // under `run`'s judge each row's own is shown as under noise.
            fmt_ratio(
                f.heldout,
                f.heldout_floor,
                clean && !crate::run_half::wanted()
            ),
            fmt_ratio(f.relit, f.relit_floor, clean),
            f.relit_model,
            fmt_matched(&f.ratio_errors, 3),
            fmt_matched(&[f.assignment, f.assignment_pure], 4),
            f.train_rel,
            f.iterations,
            f.seconds
        ));
    }
    let notes: Vec<String> = done
        .iter()
        .filter(|d| !d.note.is_empty())
        .map(|d| format!("- {}: {}\n", d.label, d.note))
        .collect();
    if !notes.is_empty() {
        md.push('\n');
        md.push_str(&notes.concat());
    }
    md.push('\n');
    for (text, _) in done.iter().filter_map(|d| d.diagnosis.as_ref()) {
        md.push_str(text);
    }
}
