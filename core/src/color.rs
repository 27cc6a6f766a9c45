//! `#rrggbb` colours as used in family files.

use std::fmt;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Rgb(pub u8, pub u8, pub u8);

/// A colour that is not `#rrggbb` or `#rgb`; each names the text that was given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ColorError {
    #[error("colour {text:?} must start with '#', as in \"#1a2b3c\"")]
    NoHash { text: String },
    #[error("colour {text:?} has a non-hex digit {digit:?}")]
    NotHex { text: String, digit: char },
    #[error("colour {text:?} must be #rrggbb or #rgb")]
    Length { text: String },
}

impl Rgb {
    pub const BLACK: Rgb = Rgb(0, 0, 0);
    pub const WHITE: Rgb = Rgb(255, 255, 255);

    /// Parses `#rrggbb` (case-insensitive) or `#rgb`.
    pub fn parse(text: &str) -> Result<Self, ColorError> {
        let hex = text
            .strip_prefix('#')
            .ok_or_else(|| ColorError::NoHash { text: text.into() })?;
        let digit = |c: char| {
            c.to_digit(16)
                .map(|d| d as u8)
                .ok_or_else(|| ColorError::NotHex {
                    text: text.into(),
                    digit: c,
                })
        };
        let digits: Vec<u8> = hex.chars().map(digit).collect::<Result<_, _>>()?;
        match digits.as_slice() {
            [r, g, b] => Ok(Rgb(r * 17, g * 17, b * 17)),
            [r1, r2, g1, g2, b1, b2] => Ok(Rgb(r1 * 16 + r2, g1 * 16 + g2, b1 * 16 + b2)),
            _ => Err(ColorError::Length { text: text.into() }),
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
        assert_eq!(
            Rgb::parse("ff8000").unwrap_err().to_string(),
            "colour \"ff8000\" must start with '#', as in \"#1a2b3c\""
        );
        assert!(matches!(
            Rgb::parse("#ff80"),
            Err(ColorError::Length { text }) if text == "#ff80"
        ));
        assert!(matches!(
            Rgb::parse("#gg8000"),
            Err(ColorError::NotHex { digit: 'g', .. })
        ));
        assert_eq!(Rgb(1, 2, 255).to_string(), "#0102ff");
    }
}
