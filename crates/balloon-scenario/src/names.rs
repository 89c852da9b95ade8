//! Parameter names as the library writes them, and as each front end spells them.
//!
//! Library errors name a parameter by its Rust / scenario name in backticks (`` `dt` ``,
//! `` `newton_iterations` ``, `` `volume_solver` ``). [`PARAMETERS`] is the one table of those
//! names with the command-line flag that sets each; [`respell`] rewrites a message for the
//! command line (`--dt`) or for Python keywords (`dt=`). Text without a backticked name of the
//! table is left unchanged.
//!
//! ```
//! use balloon_scenario::names::{Spelling, respell};
//! let m = "try a smaller `dt` or more `newton_iterations`; `gas` = volume needs `static`";
//! assert_eq!(
//!     respell(m, Spelling::Flag),
//!     "try a smaller --dt or more --newton-iters; --gas volume needs --static"
//! );
//! assert_eq!(
//!     respell(m, Spelling::Keyword),
//!     "try a smaller dt= or more newton_iters=; gas=volume needs static="
//! );
//! // A name that is not a parameter stays as it is.
//! assert_eq!(respell("mesh `builtin:cube`", Spelling::Flag), "mesh `builtin:cube`");
//! ```

use crate::range::ValueError;

/// Every parameter name the library writes in messages, with the command-line flag that sets
/// it (without `--`). The scenario keys are the flags with `_` for `-` (their Python keyword);
/// the other names are fields of the library's parameter structs (`BackwardEulerParams`,
/// `CellVolumeParams`, `SpringParams`, the builders) and name the flag that sets them.
pub const PARAMETERS: &[(&str, &str)] = &[
    // The scenario keys of every system (`crate::keys`: each key's `name`).
    ("ambient", "ambient"),
    ("band_voxels", "band-voxels"),
    ("bending", "bending"),
    ("box", "box"),
    ("c1", "c1"),
    ("c2", "c2"),
    ("cells", "cells"),
    ("cg_max_iters", "cg-max-iters"),
    ("cg_tol", "cg-tol"),
    ("color", "color"),
    ("color_range", "color-range"),
    ("conductance", "conductance"),
    ("copies", "copies"),
    ("correction", "correction"),
    ("damping", "damping"),
    ("damping_radius", "damping-radius"),
    ("damping_shear", "damping-shear"),
    ("damping_structural", "damping-structural"),
    ("density", "density"),
    ("density_threshold", "density-threshold"),
    ("diagonal_damping", "diagonal-damping"),
    ("diagonal_stiffness", "diagonal-stiffness"),
    ("dim", "dim"),
    ("drag", "drag"),
    ("drag_damping", "drag-damping"),
    ("drag_stiffness", "drag-stiffness"),
    ("dt", "dt"),
    ("edge_stiffness", "edge-stiffness"),
    ("fill_iterations", "fill-iterations"),
    ("floor_height", "floor-height"),
    ("follower_term", "follower-term"),
    ("format", "format"),
    ("frame_every", "frame-every"),
    ("gamma", "gamma"),
    ("gas", "gas"),
    ("gif", "gif"),
    ("gravity", "gravity"),
    ("image_size", "image-size"),
    ("inexact_forcing", "inexact-forcing"),
    ("inner_mass", "inner-mass"),
    ("inner_pressure", "inner-pressure"),
    ("inner_radius", "inner-radius"),
    ("integrator", "integrator"),
    ("jm", "jm"),
    ("json", "json"),
    ("k_radius", "k-radius"),
    ("k_shear", "k-shear"),
    ("k_shear_left", "k-shear-left"),
    ("k_shear_right", "k-shear-right"),
    ("k_structural", "k-structural"),
    ("lattice_frames", "lattice-frames"),
    ("leak_conductance", "leak-conductance"),
    ("length", "length"),
    ("level", "level"),
    ("linear_solver", "linear-solver"),
    ("load", "load"),
    ("lumped_masses", "lumped-masses"),
    ("mass_damping", "mass-damping"),
    ("material", "material"),
    ("material_preset", "material-preset"),
    ("mu", "mu"),
    ("newton_iters", "newton-iters"),
    ("newton_tol", "newton-tol"),
    ("no_box", "no-box"),
    ("ogden_alpha", "ogden-alpha"),
    ("ogden_mu", "ogden-mu"),
    ("out", "out"),
    ("outer_mass", "outer-mass"),
    ("outer_radius", "outer-radius"),
    ("over_relaxation", "over-relaxation"),
    ("overwrite", "overwrite"),
    ("p_in", "p-in"),
    ("p_subs", "p-subs"),
    ("particles", "particles"),
    ("pcg_preconditioner", "pcg-preconditioner"),
    ("pin", "pin"),
    ("pin_stiffness", "pin-stiffness"),
    ("poisson", "poisson"),
    ("pov", "pov"),
    ("pressure", "pressure"),
    ("pressures", "pressures"),
    ("pump_rate", "pump-rate"),
    ("rays", "rays"),
    ("render", "render"),
    ("resolution", "resolution"),
    ("restitution", "restitution"),
    ("scale", "scale"),
    ("scene", "scene"),
    ("slices", "slices"),
    ("smoothing_iterations", "smoothing-iterations"),
    ("smoothing_weight", "smoothing-weight"),
    ("soft_diagonals", "soft-diagonals"),
    ("speed_tol", "speed-tol"),
    ("sphere", "sphere"),
    ("stability", "stability"),
    ("stacks", "stacks"),
    ("static", "static"),
    ("steps", "steps"),
    ("stiffness_damping", "stiffness-damping"),
    ("stretches", "stretches"),
    ("supply_pressure", "supply-pressure"),
    ("tangent", "tangent"),
    ("thickness", "thickness"),
    ("thickness_file", "thickness-file"),
    ("thickness_prediction", "thickness-prediction"),
    ("thickness_rule", "thickness-rule"),
    ("tolerance", "tolerance"),
    ("transform", "transform"),
    ("tubes", "tubes"),
    ("until_converged", "until-converged"),
    ("until_settled", "until-settled"),
    ("up", "up"),
    ("valence_normalization", "valence-normalization"),
    ("volume_projection", "volume-projection"),
    ("volume_ratio", "volume-ratio"),
    ("volume_ratios", "volume-ratios"),
    ("volume_solver", "volume-solver"),
    ("volume_tol", "volume-tol"),
    ("voxels_per_cell", "voxels-per-cell"),
    ("yeoh", "yeoh"),
    ("young", "young"),
    // Fields of the library's parameter structs and builders, by the flag that sets them.
    ("adaptive_relaxation", "over-relaxation"),
    ("ambient_pressure", "ambient"),
    ("box_size", "box"),
    ("edge_damping", "damping"),
    ("gauge_pressure", "pressure"),
    ("linear_tolerance", "cg-tol"),
    ("max_linear_iterations", "cg-max-iters"),
    ("newton_iterations", "newton-iters"),
    ("newton_tolerance", "newton-tol"),
    ("static_solve", "static"),
    ("wall_bending", "bending"),
];

/// Parameters whose messages keep the library's name beside the front end's spelling
/// (`` `correction` (--correction) = scaling``): the settings of the cell-volume solver, which
/// the constraint crate's errors name as `CellVolumeParams` does and users of both the library
/// and the command line read in that form.
pub const NAMED_TOO: &[&str] = &["adaptive_relaxation", "correction", "over_relaxation"];

/// The flag (without `--`) of parameter `name`, if it is one.
pub fn flag_of(name: &str) -> Option<&'static str> {
    PARAMETERS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(_, flag)| flag)
}

/// How a front end spells a parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spelling {
    /// The command line: `--dt`; `` `dt` = 0.5 `` becomes `--dt 0.5`.
    Flag,
    /// Python keywords: `dt=`; `` `dt` = 0.5 `` becomes `dt=0.5`.
    Keyword,
}

impl Spelling {
    /// The parameter set by `flag` as this front end writes it, with `value` when there is one.
    fn write(self, flag: &str, value: Option<&str>) -> String {
        match (self, value) {
            (Spelling::Flag, Some(v)) => format!("--{flag} {v}"),
            (Spelling::Flag, None) => format!("--{flag}"),
            (Spelling::Keyword, v) => format!("{}={}", flag.replace('-', "_"), v.unwrap_or("")),
        }
    }
}

/// The message with every backticked parameter name of [`PARAMETERS`] spelled for a front end:
///
/// - `` `name` = value`` (the value up to the next space or punctuation) becomes `--flag value`
///   ([`Spelling::Flag`]) or `name=value` ([`Spelling::Keyword`]);
/// - `` `name` `` alone becomes `--flag` or `name=`;
/// - after the word `parameter` (`` invalid parameter `name` = value``), and for the names of
///   [`NAMED_TOO`], the name is kept and the front end's spelling added:
///   `` invalid parameter `name` (--flag) = value``.
///
/// Backticked text that is not a parameter name (a path, a selector, a table key such as
/// `` `run.dt` ``) and text without backticks are left as they are.
pub fn respell(message: &str, spelling: Spelling) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(open) = rest.find('`') {
        let (before, tail) = rest.split_at(open);
        out.push_str(before);
        let Some(close) = tail[1..].find('`') else {
            out.push_str(tail);
            return out;
        };
        let name = &tail[1..=close];
        let after = &tail[close + 2..];
        let Some(flag) = flag_of(name) else {
            out.push_str(&tail[..close + 2]);
            rest = after;
            continue;
        };
        if out.ends_with("parameter ") || NAMED_TOO.contains(&name) {
            out.push_str(&format!("`{name}` ({})", spelling.write(flag, None)));
            rest = after;
            continue;
        }
        match after.strip_prefix(" = ") {
            Some(value_on) => {
                let end = value_on
                    .find(|c: char| c.is_whitespace() || matches!(c, ',' | ';' | ')' | '('))
                    .unwrap_or(value_on.len());
                let (value, more) = value_on.split_at(end);
                // A value ending a clause keeps its punctuation (`dt` = 0.5: ...).
                let (value, colon) = match value.strip_suffix(':') {
                    Some(v) => (v, ":"),
                    None => (value, ""),
                };
                out.push_str(&spelling.write(flag, Some(value)));
                out.push_str(colon);
                rest = more;
            }
            None => {
                out.push_str(&spelling.write(flag, None));
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// A value error as a front end writes it: `invalid value '5.0' for '--dt <DT>': must be a
/// finite number in (0, 1]` ([`Spelling::Flag`], the form the command-line parser uses for a
/// value it cannot parse, so that both read alike) or `` invalid value '5.0' for dt=: ...``.
/// `typed` is the text the user gave for the value, shown instead of the library's form when
/// known (a list's element for an error about one).
pub fn value_message(e: &ValueError, spelling: Spelling, typed: Option<&str>) -> String {
    let value = typed.unwrap_or(&e.value);
    let flag = flag_of(&e.name)
        .map(str::to_owned)
        .unwrap_or_else(|| e.name.replace('_', "-"));
    let param = match spelling {
        Spelling::Flag => format!(
            "'--{flag} <{}>'",
            flag.to_ascii_uppercase().replace('-', "_")
        ),
        Spelling::Keyword => format!("{}=", flag.replace('-', "_")),
    };
    e.message(&param, value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_flags_are_kebab_case() {
        for (i, (name, flag)) in PARAMETERS.iter().enumerate() {
            assert!(
                PARAMETERS[..i].iter().all(|(n, _)| n != name),
                "{name} twice"
            );
            assert!(
                flag.bytes()
                    .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-'),
                "{flag}"
            );
        }
    }

    #[test]
    fn values_punctuation_and_the_invalid_parameter_phrase() {
        let m = "invalid parameter `dt` = 2: use `dt` = 0.1.";
        assert_eq!(
            respell(m, Spelling::Flag),
            "invalid parameter `dt` (--dt) = 2: use --dt 0.1."
        );
        assert_eq!(
            respell(
                "invalid `over_relaxation` = 1.5e0: must be 1",
                Spelling::Flag
            ),
            "invalid `over_relaxation` (--over-relaxation) = 1.5e0: must be 1"
        );
        assert_eq!(
            respell(
                "`gamma` = 1.2 is a parameter of `gas` = polytropic, but",
                Spelling::Flag
            ),
            "--gamma 1.2 is a parameter of --gas polytropic, but"
        );
        assert_eq!(
            respell("invalid `gamma` = 0: must be positive", Spelling::Flag),
            "invalid --gamma 0: must be positive"
        );
        assert_eq!(respell("(`mu`, `jm`)", Spelling::Keyword), "(mu=, jm=)");
        assert_eq!(respell("no `closing", Spelling::Flag), "no `closing");
        assert_eq!(respell("`run.dt`: x", Spelling::Flag), "`run.dt`: x");
    }

    #[test]
    fn value_errors_read_like_the_parser_s() {
        let e = ValueError::new(
            "dt",
            "5.0".into(),
            Some("must be a finite number in (0, 1]".into()),
        );
        assert_eq!(
            value_message(&e, Spelling::Flag, None),
            "invalid value '5.0' for '--dt <DT>': must be a finite number in (0, 1]"
        );
        assert_eq!(
            value_message(&e, Spelling::Flag, Some("5e0")),
            "invalid value '5e0' for '--dt <DT>': must be a finite number in (0, 1]"
        );
        assert_eq!(
            value_message(&e, Spelling::Keyword, None),
            "invalid value '5.0' for dt=: must be a finite number in (0, 1]"
        );
    }
}
