//! What every chart volcast draws with plotters shares: the embedded label font
//! (registered once as plotters' "sans-serif", so no system font library is
//! needed; `assets/fonts/README.md`) and the PNG encoding of an RGB buffer.

use std::sync::OnceLock;

use super::overlay::FONT;

/// Registers the embedded font as plotters' "sans-serif" (once per process);
/// an error names the problem.
pub(crate) fn register_font() -> Result<(), String> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT)
                .map_err(|_| "the embedded font is not a valid TrueType file".to_string())
        })
        .clone()
}

/// The PNG file of an RGB buffer of `width x height` pixels (row by row).
pub(crate) fn encode_rgb_png(width: u32, height: u32, rgb: Vec<u8>) -> Result<Vec<u8>, String> {
    if rgb.len() as u64 != 3 * u64::from(width) * u64::from(height) {
        return Err("the plot buffer has the wrong size".to_string());
    }
    super::encode::encode_png(
        width,
        height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &rgb,
    )
    .map_err(|e| e.to_string())
}
