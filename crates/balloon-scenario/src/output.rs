//! What a run writes, as data (the `[output]` table): the output folder, the frame format and
//! interval, and the pictures. The library writes nothing; a front end's job runner reads this.
//!
//! ```
//! use balloon_scenario::output::{ColorRange, RenderSpec, parse_image_size};
//! assert_eq!(parse_image_size("800x600"), Ok((800, 600)));
//! assert_eq!("1:1.5".parse::<ColorRange>(), Ok(ColorRange::Fixed(1.0, 1.5)));
//! let r = RenderSpec::parse("0,100,last").unwrap();
//! assert!(r.last && r.steps.contains(&100));
//! ```

use crate::serde_text;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

/// File format of surface frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FrameFormat {
    /// Wavefront OBJ.
    #[default]
    Obj,
    /// Binary little-endian PLY.
    Ply,
    /// VTK XML PolyData `.vtp` with the fields (velocity, thickness, stretch, ...) and a
    /// `series.pvd` time series for ParaView.
    Vtk,
    /// One USD stage `run.usda` for the whole run (Blender, Houdini, usdview): a mesh per body,
    /// time-sampled points, the fields as primvars.
    Usd,
}

impl FrameFormat {
    /// The frame files' extension.
    pub fn extension(self) -> &'static str {
        match self {
            FrameFormat::Obj => "obj",
            FrameFormat::Ply => "ply",
            FrameFormat::Vtk => "vtp",
            FrameFormat::Usd => "usda",
        }
    }
}

/// Defines `FromStr` and `Display` of an enum of named choices (the names of the scenario
/// files and the command line), and its serde form as those names.
macro_rules! choices {
    ($t:ty, $what:literal, [$(($v:path, $name:literal)),+ $(,)?]) => {
        impl $t {
            /// The names this parameter takes.
            pub const NAMES: &'static [&'static str] = &[$($name),+];

            /// This value's name.
            pub fn name(&self) -> &'static str {
                match self {
                    $($v => $name,)+
                }
            }
        }
        impl std::str::FromStr for $t {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($name => Ok($v),)+
                    _ => Err(format!(
                        "`{s}` is not {} ({})",
                        $what,
                        Self::NAMES.join(", ")
                    )),
                }
            }
        }
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
        impl serde::Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.collect_str(self)
            }
        }
        impl<'de> serde::Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let s = String::deserialize(d)?;
                s.parse().map_err(serde::de::Error::custom)
            }
        }
    };
}
pub(crate) use choices;

choices!(
    FrameFormat,
    "a frame format",
    [
        (FrameFormat::Obj, "obj"),
        (FrameFormat::Ply, "ply"),
        (FrameFormat::Vtk, "vtk"),
        (FrameFormat::Usd, "usd")
    ]
);

/// The field that colours renders, the GIF and the POV scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ColorField {
    /// Shell thickness per face (inflate only), shown in mm.
    Thickness,
    /// Mean in-plane stretch sqrt(A/A0) per face, against the rest (or initial) shape.
    Stretch,
    /// Vertex speed |v|, m/s.
    Speed,
    /// Plain shaded surface, no legend.
    None,
}

choices!(
    ColorField,
    "a colour field",
    [
        (ColorField::Thickness, "thickness"),
        (ColorField::Stretch, "stretch"),
        (ColorField::Speed, "speed"),
        (ColorField::None, "none")
    ]
);

/// How the colour-map range of pictures is chosen (`color_range`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum ColorRange {
    /// Smallest to largest finite value.
    #[default]
    Full,
    /// 2nd to 98th percentile of the finite values.
    Robust,
    /// A fixed range.
    Fixed(f64, f64),
}

impl FromStr for ColorRange {
    type Err = String;

    /// `full`, `robust` or `MIN:MAX` (finite, MIN < MAX).
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "full" => return Ok(ColorRange::Full),
            "robust" => return Ok(ColorRange::Robust),
            _ => {}
        }
        let bad = || format!("`{s}`: expected full, robust or MIN:MAX with finite MIN < MAX");
        let (a, b) = s.split_once(':').ok_or_else(bad)?;
        let lo: f64 = a.trim().parse().map_err(|_| bad())?;
        let hi: f64 = b.trim().parse().map_err(|_| bad())?;
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(bad());
        }
        Ok(ColorRange::Fixed(lo, hi))
    }
}

impl fmt::Display for ColorRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ColorRange::Full => f.write_str("full"),
            ColorRange::Robust => f.write_str("robust"),
            ColorRange::Fixed(lo, hi) => write!(f, "{lo}:{hi}"),
        }
    }
}

impl ColorRange {
    /// The range of `values` (non-finite ones ignored) under this rule; `None` when no value
    /// is finite (and the rule is not fixed).
    pub fn of<'a>(self, values: impl Iterator<Item = &'a f64>) -> Option<(f64, f64)> {
        if let ColorRange::Fixed(lo, hi) = self {
            return Some((lo, hi));
        }
        let mut v: Vec<f64> = values.copied().filter(|v| v.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_unstable_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Some(match self {
            ColorRange::Robust => (at(0.02), at(0.98)),
            _ => (v[0], v[v.len() - 1]),
        })
    }
}

/// Parses `WxH` (each side 32 to 8192 pixels).
pub fn parse_image_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}`: expected WxH in pixels, e.g. 640x480 (each side 32..=8192)");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if !(32..=8192).contains(&w) || !(32..=8192).contains(&h) {
        return Err(bad());
    }
    Ok((w, h))
}

/// An image size `(w, h)` as `"WxH"`.
mod image_size_text {
    use serde::{Deserialize, Deserializer, Serializer};

    /// Serializes as `"WxH"`.
    pub fn serialize<S: Serializer>(v: &(u32, u32), s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(&format_args!("{}x{}", v.0, v.1))
    }

    /// Deserializes `"WxH"`.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<(u32, u32), D::Error> {
        super::parse_image_size(&String::deserialize(d)?).map_err(serde::de::Error::custom)
    }
}

/// Which steps `render` asks for.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RenderSpec {
    /// Every written frame.
    pub all: bool,
    /// The final state.
    pub last: bool,
    /// Explicit step numbers.
    pub steps: BTreeSet<usize>,
}

impl RenderSpec {
    /// Parses `last`, `all` or a comma list of step numbers and `last`; the error names the
    /// parameter (`` invalid `render` `first`: ...``).
    pub fn parse(s: &str) -> Result<Self, String> {
        let mut spec = RenderSpec::default();
        let help = "expected `last`, `all`, or a comma list of step numbers and `last` (e.g. `0,100,last`)";
        if s.trim().is_empty() {
            return Err(format!("invalid `render` ``: {help}"));
        }
        for item in s.split(',').map(str::trim) {
            match item {
                "last" => spec.last = true,
                "all" => spec.all = true,
                _ => {
                    let n: usize = item.parse().map_err(|_| {
                        format!("invalid `render` `{s}`: `{item}` is not a step number; {help}")
                    })?;
                    spec.steps.insert(n);
                }
            }
        }
        Ok(spec)
    }
}

/// The `[output]` table: where and what a run writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Output {
    /// Output folder: frames, final mesh, `stats.jsonl`, `summary.json`; `None` writes nothing.
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier run in `out` (only files a run writes).
    pub overwrite: bool,
    /// Print the summary as one JSON line (the last line on stdout); no progress bar.
    pub json: bool,
    /// Frame file format.
    #[serde(with = "serde_text")]
    pub format: FrameFormat,
    /// Write a frame every this many steps (0: only the first and final frames where the
    /// system allows it).
    pub frame_every: usize,
    /// PNG renders of chosen steps: `last`, `all` or a comma list of step numbers and `last`.
    pub render: Option<String>,
    /// The colour of renders, GIF and POV scene (`None`: the system's).
    #[serde(with = "serde_text::option")]
    pub color: Option<ColorField>,
    /// Write `run.gif`, an animation of the written frames.
    pub gif: bool,
    /// Write `final.pov`, a POV-Ray scene of the last frame.
    pub pov: bool,
    /// Size of the PNG renders and GIF frames, pixels (width, height).
    #[serde(with = "image_size_text")]
    pub image_size: (u32, u32),
    /// Colour-map range.
    #[serde(with = "serde_text")]
    pub color_range: ColorRange,
    /// Also write the deformed lattice as VTK with each frame (volumetric bodies only).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub lattice_frames: bool,
}

impl Output {
    /// The defaults with frames every `frame_every` steps.
    pub fn every(frame_every: usize) -> Self {
        Self {
            out: None,
            overwrite: false,
            json: false,
            format: FrameFormat::Obj,
            frame_every,
            render: None,
            color: None,
            gif: false,
            pov: false,
            image_size: (640, 480),
            color_range: ColorRange::Full,
            lattice_frames: false,
        }
    }

    /// Checks the pictures against the output folder and the colours `available` from system
    /// `system` (before any work) and returns the parsed `render` spec.
    pub fn check_pictures(
        &self,
        system: &str,
        available: &[ColorField],
    ) -> Result<Option<RenderSpec>, String> {
        let spec = self.render.as_deref().map(RenderSpec::parse).transpose()?;
        let wants = spec.is_some() || self.gif || self.pov;
        if wants && self.out.is_none() {
            let name = if spec.is_some() {
                "render"
            } else if self.gif {
                "gif"
            } else {
                "pov"
            };
            return Err(format!(
                "`{name}` needs `out` DIR (images are written into the output folder)"
            ));
        }
        if let Some(c) = self.color
            && c != ColorField::None
            && !available.contains(&c)
        {
            return Err(format!(
                "invalid `color` = {c}: `{system}` has no such field (available: {}, none)",
                available
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        Ok(spec)
    }
}

impl Default for Output {
    fn default() -> Self {
        Self::every(10)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_specs_and_sizes_parse_or_explain() {
        let s = RenderSpec::parse("0, 50,last").unwrap();
        assert!(s.last && !s.all);
        assert_eq!(s.steps.into_iter().collect::<Vec<_>>(), vec![0, 50]);
        assert!(RenderSpec::parse("all").unwrap().all);
        for bad in ["", "first", "1,,2", "-3", "1.5"] {
            let e = RenderSpec::parse(bad).unwrap_err().to_string();
            assert!(e.contains("`render`") && e.contains("last"), "{bad}: {e}");
        }
        assert_eq!(parse_image_size("320x200"), Ok((320, 200)));
        assert!(parse_image_size("320").is_err());
        assert!(parse_image_size("10x10").unwrap_err().contains("640x480"));
    }

    #[test]
    fn color_ranges_parse_and_robust_ignores_outliers() {
        assert_eq!("full".parse::<ColorRange>(), Ok(ColorRange::Full));
        assert_eq!("robust".parse::<ColorRange>(), Ok(ColorRange::Robust));
        assert_eq!(
            "1:1.5".parse::<ColorRange>(),
            Ok(ColorRange::Fixed(1.0, 1.5))
        );
        for bad in ["", "2:1", "1:1", "a:b", "1", "nan:2", "0:inf"] {
            assert!(
                bad.parse::<ColorRange>().unwrap_err().contains("MIN:MAX"),
                "{bad}"
            );
        }
        // 100 values 1.00..1.99 plus one outlier and one NaN.
        let mut v: Vec<f64> = (0..100).map(|i| 1.0 + f64::from(i) / 100.0).collect();
        v.push(50.0);
        v.push(f64::NAN);
        assert_eq!(ColorRange::Full.of(v.iter()), Some((1.0, 50.0)));
        let (lo, hi) = ColorRange::Robust.of(v.iter()).unwrap();
        assert!(
            (lo - 1.02).abs() < 1e-12 && (hi - 1.98).abs() < 1e-12,
            "{lo} {hi}"
        );
        assert_eq!(ColorRange::Fixed(0.0, 2.0).of(v.iter()), Some((0.0, 2.0)));
        assert_eq!(ColorRange::Robust.of([f64::NAN].iter()), None);
    }

    #[test]
    fn pictures_need_a_folder_and_a_field_of_the_system() {
        let mut o = Output {
            render: Some("last".into()),
            ..Output::default()
        };
        assert!(
            o.check_pictures("inflate", &[])
                .unwrap_err()
                .contains("`out`")
        );
        o.out = Some("o".into());
        o.color = Some(ColorField::Thickness);
        let e = o
            .check_pictures("volumetric", &[ColorField::Stretch])
            .unwrap_err();
        assert!(e.starts_with("invalid `color` = thickness"), "{e}");
    }
}
