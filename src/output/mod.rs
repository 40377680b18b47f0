//! From films to files: grey windows and colour, stereo layouts, encoders, and
//! atomic writes. Knows nothing about render modes beyond what a film holds and
//! whether its values are intensities, depths or RGBA.

pub mod display;
pub mod encode;
pub mod stereo;
pub mod write;

pub use display::{DisplayKind, Window};
pub use write::write_atomic;

use std::path::{Path, PathBuf};

/// Which eye an image belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Eye {
    /// No stereo.
    Mono,
    /// Left eye (turned -angle/2).
    Left,
    /// Right eye (turned +angle/2).
    Right,
}

/// `{out}/{pass}_{frame:04}{_left|_right}.{ext}` (SCENES.md "Outputs").
pub fn frame_path(out: &Path, pass: &str, frame: usize, eye: Eye, ext: &str) -> PathBuf {
    let suffix = match eye {
        Eye::Mono => "",
        Eye::Left => "_left",
        Eye::Right => "_right",
    };
    out.join(format!("{pass}_{frame:04}{suffix}.{ext}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert_eq!(
            frame_path(Path::new("out/x"), "mip", 7, Eye::Left, "png"),
            PathBuf::from("out/x/mip_0007_left.png")
        );
        assert_eq!(
            frame_path(Path::new("o"), "a", 12345, Eye::Mono, "nrrd"),
            PathBuf::from("o/a_12345.nrrd")
        );
    }
}
