//! [`SizeArgs`]: `--size`, `--radius` and `--bend`, the primitive sizes shared by `fit`
//! (the candidates') and `synth` (the true primitives').

use clap::Args;

/// The primitive sizes, in scene units; each command states its own defaults (`fit`
/// derives them from the cloud, `synth` has per-scene values).
#[derive(Debug, Clone, Copy, Args)]
pub struct SizeArgs {
    /// Main extent in scene units: square side, disk/sphere diameter, cylinder length.
    #[arg(allow_hyphen_values = true, long)]
    pub size: Option<f64>,
    /// Tube radius of cylinders and elbows.
    #[arg(allow_hyphen_values = true, long)]
    pub radius: Option<f64>,
    /// Elbow bend radius (centre line).
    #[arg(allow_hyphen_values = true, long)]
    pub bend: Option<f64>,
}

#[cfg(test)]
mod tests {
    use clap::{Args, Command, FromArgMatches};

    use crate::commands::{fit::FitArgs, synth::SynthArgs};

    /// The help text of `--flag` in the command built from `A`.
    fn help_of<A: Args>(flag: &str) -> String {
        let command = A::augment_args(Command::new("test"));
        let arg = command
            .get_arguments()
            .find(|a| a.get_long() == Some(flag))
            .unwrap_or_else(|| panic!("no --{flag}"));
        arg.get_help().map(ToString::to_string).unwrap_or_default()
    }

    #[test]
    fn each_command_states_its_own_size_defaults_and_parses_them() {
        assert!(help_of::<FitArgs>("radius").ends_with("[default: size / 10]"));
        assert!(help_of::<FitArgs>("size").contains("bounding-box diagonal / 8"));
        assert!(help_of::<SynthArgs>("size").contains("pipe segment length [default: 1]"));
        assert!(help_of::<SynthArgs>("bend").ends_with("[default: size / 2]"));
        let command = FitArgs::augment_args(Command::new("fit"));
        let matches = command
            .try_get_matches_from(["fit", "scan.ply", "--size", "2", "--bend", "0.5"])
            .expect("valid flags");
        let args = FitArgs::from_arg_matches(&matches).expect("parsed");
        assert_eq!(
            (args.sizes.size, args.sizes.radius, args.sizes.bend),
            (Some(2.0), None, Some(0.5))
        );
    }
}
