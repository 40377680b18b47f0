//! `[[clip]]` planes: a point and a normal in world coordinates, an offset along
//! the normal, a cap for surface passes, and the passes they apply to.

use std::collections::BTreeMap;
use std::ops::Range;

use toml::Spanned;

use super::Resolver;
use crate::scene::diag::{quoted_list, suggest};
use crate::scene::schema::ClipTable;
use crate::scene::{Clip, RenderPass};

impl Resolver<'_> {
    pub(super) fn clips(
        &mut self,
        tables: Option<&[Spanned<ClipTable>]>,
        passes: &[RenderPass],
    ) -> Vec<Clip> {
        let mut clips = Vec::new();
        let mut names: BTreeMap<String, Range<usize>> = BTreeMap::new();
        for t in tables.unwrap_or_default() {
            let v = t.get_ref();
            let name = v.name.as_ref().and_then(|n| {
                let s = n.get_ref();
                let valid = !s.is_empty()
                    && s.chars()
                        .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_'));
                if !valid {
                    self.err(n.span(), format!("[[clip]] name = \"{s}\": expected letters, digits, '-' and '_' (the name is used in keys such as clip.NAME.offset)"));
                    return None;
                }
                if names.insert(s.clone(), n.span()).is_some() {
                    self.err(
                        n.span(),
                        format!("two [[clip]] planes are named `{s}`: give each its own name"),
                    );
                    return None;
                }
                Some(s.clone())
            });
            let point = match &v.point {
                Some(p) => self.vec3("[[clip]] point", p, false),
                None => {
                    self.err(t.span(), "[[clip]] needs `point = [x, y, z]`: a point of the plane, in world coordinates");
                    None
                }
            };
            let normal = match &v.normal {
                Some(n) => self.vec3("[[clip]] normal", n, true),
                None => {
                    self.err(t.span(), "[[clip]] needs `normal = [x, y, z]`: the plane's normal in world coordinates, pointing into the half-space that is removed");
                    None
                }
            };
            let offset = self.number(
                "[[clip]] offset",
                &v.offset,
                0.0,
                |_| true,
                "a distance in world units (the plane moves along its normal)",
            );
            let cap = v.cap.as_ref().is_some_and(|c| *c.get_ref());
            let selected = v.passes.as_ref().map(|list| {
                if list.get_ref().is_empty() {
                    self.err(list.span(), "[[clip]] passes = []: expected the names of the passes the plane applies to (leave `passes` out for every pass)");
                }
                let mut out = Vec::new();
                for p in list.get_ref() {
                    if passes.iter().any(|q| q.name == *p.get_ref()) {
                        out.push(p.get_ref().clone());
                    } else {
                        let hint = suggest(p.get_ref(), passes.iter().map(|q| q.name.as_str()))
                            .map(|n| format!("; did you mean `{n}`?"))
                            .unwrap_or_default();
                        self.err(
                            p.span(),
                            format!(
                                "[[clip]] passes: no pass is named `{}`: the passes are {}{hint}",
                                p.get_ref(),
                                quoted_list(passes.iter().map(|q| q.name.as_str()))
                            ),
                        );
                    }
                }
                out
            });
            let (Some(point), Some(normal)) = (point, normal) else {
                continue;
            };
            let clip = Clip {
                name,
                point,
                normal: normal.normalize(),
                offset,
                cap,
                passes: selected,
            };
            if cap
                && !passes
                    .iter()
                    .any(|p| clip.applies_to(&p.name) && p.mode.caps_clips())
            {
                self.warnings.push(format!(
                    "[[clip]]{}: cap = true has no effect: it caps surface and depth passes, and the plane applies to none",
                    clip.name.as_ref().map(|n| format!(" `{n}`")).unwrap_or_default()
                ));
            }
            clips.push(clip);
        }
        clips
    }
}
