//! Errors worded for the command line: one line, with the library's option names
//! replaced by the flags that set them (`size` → `--size`).

use primfit_core::Error;

/// Library option names (fields of the options types) and the flag of any command that
/// sets each. The library names options by their fields and never by a flag; a name
/// that no flag sets is printed as it is.
const FLAGS: &[(&str, &str)] = &[
    // every command
    ("threads", "-j/--threads"),
    // fit
    ("kinds", "--types"),
    ("size", "--size"),
    ("radius", "--radius"),
    ("bend", "--bend"),
    ("spacing", "--spacing"),
    ("origin", "--origin"),
    ("sample_spacing", "--sample-spacing"),
    ("alpha", "--alpha"),
    ("beta", "--beta"),
    ("cap", "--cap"),
    ("primitive_weight", "--weights"),
    ("point_weight", "--weights"),
    ("max_iterations", "--max-iterations"),
    ("search_points", "--search-points"),
    ("work_budget", "--work-budget"),
    ("rounds", "--refine-rounds"),
    ("mesh_model", "--mesh-model"),
    ("steps", "--steps"),
    ("burn_in", "--burn-in"),
    ("rate", "--noise-rate"),
    ("sigma", "--sigma"),
    ("probability", "--prior"),
    // synth
    ("side", "--size"),
    ("segment_length", "--size"),
    ("length", "--length"),
    ("width", "--width"),
    ("height", "--height"),
    ("segments", "--segments"),
    ("mask", "--mask"),
    ("points", "--points"),
    ("jitter", "--jitter"),
    ("range_noise", "--jitter"),
    ("drift", "--drift"),
    ("offset", "--offset"),
    ("angle", "--angle"),
    ("inliers", "--inliers"),
    ("outliers", "--outliers"),
    ("objects", "--objects"),
    ("translation", "--translation"),
    ("distractors", "--distractors"),
    // register
    ("count", "--count"),
    ("fixed_translation", "--at"),
    ("scale", "--scale-range"),
    ("initial_particles", "--initial-particles"),
    ("particles", "--particles"),
    ("max_rounds", "--max-rounds"),
    ("min_support", "--min-support"),
    ("inlier_distance", "--inlier-distance"),
    ("min_confidence", "--min-confidence"),
    // eval
    ("coverage_tau", "--tau"),
    // render, view
    ("view", "--view"),
    ("image_width", "--size"),
    ("image_height", "--size"),
    ("color_scale", "--scale"),
    ("max_points", "--max-points"),
];

/// The flag that sets the library option `name`, or `name` itself when none does.
pub fn flag_of(name: &str) -> String {
    FLAGS
        .iter()
        .find(|(option, _)| *option == name)
        .map_or(name, |(_, flag)| flag)
        .to_owned()
}

/// The whole cause chain on one line, without a backtrace. A library error is worded
/// with flags and ends the line (its message already shows its own causes); other
/// causes whose text a parent already shows are not repeated.
pub fn one_line(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let library = cause.downcast_ref::<Error>();
        let text = library.map_or_else(|| cause.to_string(), |e| e.describe_with(&flag_of));
        if !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
        if library.is_some() {
            break;
        }
    }
    out.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn library_names_become_flags_in_the_one_line() {
        assert_eq!(flag_of("sample_spacing"), "--sample-spacing");
        assert_eq!(flag_of("kernel_shrink"), "kernel_shrink");
        let core = Error::out_of_range("side", -1.0, "positive and finite");
        let e = anyhow::Error::from(core).context("hallway");
        assert_eq!(
            one_line(&e),
            "hallway: --size must be positive and finite, got -1"
        );
    }

    #[test]
    fn every_option_has_one_flag() {
        for (k, (option, _)) in FLAGS.iter().enumerate() {
            assert!(
                FLAGS[k + 1..].iter().all(|(other, _)| other != option),
                "{option} is listed twice"
            );
        }
    }
}
