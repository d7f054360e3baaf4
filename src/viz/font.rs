//! Font registration for figure labels (plotters' `ab_glyph` backend needs one
//! TrueType font, read once from the system).

use super::VizError;
use plotters::style::FontStyle;
use std::sync::OnceLock;

/// Where Debian's `fonts-dejavu-core` (and a few other common packages) put a sans font.
const FONT_PATHS: [&str; 4] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();

/// Registers a system sans-serif font as `sans-serif` (idempotent). `RISKPLAN_FONT`
/// overrides the search.
pub fn ensure_registered() -> Result<(), VizError> {
    REGISTERED
        .get_or_init(|| {
            let candidates: Vec<String> = std::env::var("RISKPLAN_FONT")
                .ok()
                .into_iter()
                .chain(FONT_PATHS.iter().map(|s| s.to_string()))
                .collect();
            for path in &candidates {
                if let Ok(bytes) = std::fs::read(path) {
                    let leaked: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                    if plotters::style::register_font("sans-serif", FontStyle::Normal, leaked).is_ok() {
                        return Ok(());
                    }
                }
            }
            Err(format!(
                "figures need a TrueType font for labels: install fonts-dejavu-core (apt-get install fonts-dejavu-core) or set RISKPLAN_FONT to a .ttf file (tried {})",
                candidates.join(", ")
            ))
        })
        .clone()
        .map_err(VizError::Font)
}
