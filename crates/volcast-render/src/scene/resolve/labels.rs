//! `[[label]]` tables and the overlays of `[image]`: what is drawn into PNG frames.

use toml::Spanned;

use super::Resolver;
use crate::label::{self, Label, Position};
use crate::scene::schema::LabelTable;
use crate::scene::{Format, ImageSpec, RenderPass};

impl Resolver<'_> {
    pub(super) fn labels(
        &mut self,
        tables: Option<&[Spanned<LabelTable>]>,
        image: &ImageSpec,
        passes: &[RenderPass],
    ) -> Vec<Label> {
        let mut out = Vec::new();
        for t in tables.unwrap_or_default() {
            let v = t.get_ref();
            let Some(text) = &v.text else {
                self.err(
                    t.span(),
                    "[[label]] needs `text` (placeholders {scene}, {pass}, {frame}, {azimuth}, {elevation})",
                );
                continue;
            };
            let parts = match label::parse_text(text.get_ref()) {
                Ok(p) => p,
                Err(m) => {
                    self.err(text.span(), format!("text = {:?}: {m}", text.get_ref()));
                    continue;
                }
            };
            let position = self.choice("position", &v.position, Position::ALL, Position::TopLeft);
            let default_size = (image.height as f64 / 20.0).round().max(12.0);
            let size = self.number(
                "size",
                &v.size,
                default_size,
                |s| (4.0..=1000.0).contains(&s),
                "a font size in pixels, from 4 to 1000",
            ) as f32;
            let color = v
                .color
                .as_ref()
                .map_or([1.0; 3], |c| self.unit_color("color", c).map(|x| x as f32));
            out.push(Label {
                text: parts,
                position,
                size,
                color,
            });
        }
        let drawn = !out.is_empty() || image.scale_bar || image.colorbar;
        if drawn && image.format == Format::Nrrd {
            self.warnings.push(
                "labels, scale_bar and colorbar are drawn into PNG frames only: NRRD output holds the raw values, without them".into(),
            );
        }
        if image.colorbar && !passes.iter().any(|p| p.mode.is_intensity()) {
            self.warnings.push(
                "colorbar = true: no pass has a grey window to show (surface, composite and depth-coded passes get no colour bar)".into(),
            );
        }
        out
    }
}
