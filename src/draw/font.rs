//! The embedded font: DejaVu Sans 2.37 (Debian `fonts-dejavu-core`; licence in
//! `assets/fonts/DejaVuSans-LICENSE.txt`: Bitstream Vera licence, DejaVu changes in the
//! public domain), so that text renders identically on any machine without system fonts.

use ab_glyph::FontRef;

/// The TrueType file of DejaVu Sans.
pub const DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Family name under which [`register_plot_font`] makes the font known to `plotters`.
pub const PLOT_FAMILY: &str = "sans-serif";

/// DejaVu Sans for `imageproc` text drawing.
pub fn font() -> FontRef<'static> {
    FontRef::try_from_slice(DEJAVU_SANS).expect("the embedded DejaVu Sans is a valid TrueType font")
}

/// Registers DejaVu Sans with `plotters` as [`PLOT_FAMILY`] (idempotent, cheap after the
/// first call); plotters' `ab_glyph` backend has no other font source.
pub fn register_plot_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        for style in [
            plotters::style::FontStyle::Normal,
            plotters::style::FontStyle::Bold,
        ] {
            plotters::style::register_font(PLOT_FAMILY, style, DEJAVU_SANS)
                .unwrap_or_else(|_| unreachable!("the embedded DejaVu Sans is a valid font"));
        }
    });
}

#[cfg(test)]
mod tests {
    use ab_glyph::Font;

    #[test]
    fn the_embedded_font_has_lower_case_digits_and_signs() {
        let f = super::font();
        for c in "aZ09-.µ°".chars() {
            assert_ne!(f.glyph_id(c).0, 0, "glyph for {c:?}");
        }
    }
}
