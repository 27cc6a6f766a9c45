//! `#rrggbb` colours as used in family files.

use std::fmt;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    pub const BLACK: Rgb = Rgb(0, 0, 0);
    pub const WHITE: Rgb = Rgb(255, 255, 255);

    /// Parses `#rrggbb` (case-insensitive) or `#rgb`.
    pub fn parse(text: &str) -> Result<Self, String> {
        let hex = text
            .strip_prefix('#')
            .ok_or_else(|| format!("colour {text:?} must start with '#', as in \"#1a2b3c\""))?;
        let digit = |c: char| {
            c.to_digit(16)
                .map(|d| d as u8)
                .ok_or_else(|| format!("colour {text:?} has a non-hex digit {c:?}"))
        };
        let digits: Vec<u8> = hex.chars().map(digit).collect::<Result<_, _>>()?;
        match digits.as_slice() {
            [r, g, b] => Ok(Rgb(r * 17, g * 17, b * 17)),
            [r1, r2, g1, g2, b1, b2] => Ok(Rgb(r1 * 16 + r2, g1 * 16 + g2, b1 * 16 + b2)),
            _ => Err(format!("colour {text:?} must be #rrggbb or #rgb")),
        }
    }

    /// Relative luminance in 0..=1 (Rec. 709 weights on the encoded values): enough to tell
    /// dark from light patterns.
    pub fn luminance(self) -> f64 {
        crate::image::luminance(self.0 as f32, self.1 as f32, self.2 as f32) as f64 / 255.0
    }
}

impl fmt::Display for Rgb {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "#{:02x}{:02x}{:02x}", self.0, self.1, self.2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_long_and_short_forms_and_rejects_junk() {
        assert_eq!(Rgb::parse("#FF8000"), Ok(Rgb(255, 128, 0)));
        assert_eq!(Rgb::parse("#fff"), Ok(Rgb::WHITE));
        assert!(Rgb::parse("ff8000").is_err());
        assert!(Rgb::parse("#ff80").is_err());
        assert!(Rgb::parse("#gg8000").is_err());
        assert_eq!(Rgb(1, 2, 255).to_string(), "#0102ff");
    }
}
