//! The picture flags shared by the subcommands.

use crate::choices::ColorField;
use balloon_scenario::output::{ColorRange, Output, parse_image_size};

/// Parses `--color-range` (`full`, `robust` or `MIN:MAX`).
fn parse_color_range(s: &str) -> Result<ColorRange, String> {
    s.parse()
}

/// Picture flags shared by `inflate`, `volumetric` and `two-layer`.
#[derive(Debug, Clone, clap::Args)]
pub struct PictureArgs {
    /// Write PNG images of chosen steps into OUT/renders/: `last`, `all` (every written frame)
    /// or a comma list of step numbers and `last` (e.g. `0,100,last`). Needs --out.
    #[arg(long, value_name = "SPEC")]
    pub render: Option<String>,
    /// Colour of renders, GIF and POV scene: thickness | stretch | speed | none (default:
    /// thickness for inflate, stretch for volumetric, speed for two-layer).
    #[arg(long, value_enum)]
    pub color: Option<ColorField>,
    /// Write OUT/run.gif, an animation of the written frames (same framing and colour range in
    /// every frame). Needs --out.
    #[arg(long)]
    pub gif: bool,
    /// Write OUT/final.pov, a POV-Ray scene of the last frame. Needs --out.
    #[arg(long)]
    pub pov: bool,
    /// Size of the PNG renders and GIF frames, WxH pixels.
    #[arg(long, value_name = "WxH", default_value = "640x480", value_parser = parse_image_size)]
    pub image_size: (u32, u32),
    /// Colour-map range: `full` (smallest to largest value of the picture, or of the whole GIF),
    /// `robust` (2nd to 98th percentile, so a few outliers do not flatten the map; values
    /// beyond get the end colours) or `MIN:MAX` (fixed, e.g. `1:1.5`, to compare runs).
    #[arg(long, value_name = "full|robust|MIN:MAX", default_value = "full", value_parser = parse_color_range)]
    pub color_range: ColorRange,
}

impl PictureArgs {
    /// Sets the picture keys of `output`.
    pub fn apply(&self, output: &mut Output) {
        output.render.clone_from(&self.render);
        output.color = self.color.map(Into::into);
        output.gif = self.gif;
        output.pov = self.pov;
        output.image_size = self.image_size;
        output.color_range = self.color_range;
    }
}
