//! How a layer is drawn: fill, stroke, width (metres on the ground or pixels), opacity, dashes,
//! markers, and rules that pick a feature's colours from a property.

use serde::Deserialize;

use crate::{Feature, Value};

/// A colour with alpha, sRGB, each 0 … 255. Written `"#rrggbb"`, `"#rrggbbaa"` or `"none"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rgba(pub [u8; 4]);

impl Rgba {
    /// Transparent.
    pub const NONE: Rgba = Rgba([0, 0, 0, 0]);

    /// Parses `#rgb`, `#rrggbb`, `#rrggbbaa` or `none`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let t = s.trim();
        if t.eq_ignore_ascii_case("none") {
            return Ok(Rgba::NONE);
        }
        let bad = || format!("colour `{s}`: write #rrggbb, #rrggbbaa or none");
        let hex = t.strip_prefix('#').ok_or_else(bad)?;
        if !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(bad());
        }
        let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| bad());
        match hex.len() {
            3 => {
                let d = |i: usize| {
                    u8::from_str_radix(&hex[i..=i], 16)
                        .map(|v| v * 17)
                        .map_err(|_| bad())
                };
                Ok(Rgba([d(0)?, d(1)?, d(2)?, 255]))
            }
            6 => Ok(Rgba([byte(0)?, byte(2)?, byte(4)?, 255])),
            8 => Ok(Rgba([byte(0)?, byte(2)?, byte(4)?, byte(6)?])),
            _ => Err(bad()),
        }
    }
}

impl<'de> Deserialize<'de> for Rgba {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        Rgba::parse(&s).map_err(serde::de::Error::custom)
    }
}

/// What a width is measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    /// Metres on the ground: the line widens as the camera nears.
    #[default]
    M,
    /// Pixels: the same width at every distance (per clipmap level: the level's texels are about
    /// [`crate::layer::TEXELS_PER_PIXEL`] to a pixel where it is drawn).
    Px,
}

/// A rule: features whose `property` equals `equals` (or, without `equals`, every feature that
/// has the property, coloured from a palette by its value) take these colours. The first rule
/// that matches wins.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rule {
    /// The property looked at.
    pub property: String,
    /// The value it must have (text or number); absent: any value, coloured by a palette.
    #[serde(default)]
    pub equals: Option<toml_value::Scalar>,
    /// The fill it gets.
    #[serde(default)]
    pub fill: Option<Rgba>,
    /// The stroke it gets.
    #[serde(default)]
    pub stroke: Option<Rgba>,
    /// The stroke width it gets.
    #[serde(default)]
    pub width: Option<f64>,
}

/// A scalar from the graph's TOML.
pub mod toml_value {
    use serde::Deserialize;

    /// Text, a number or a boolean.
    #[derive(Debug, Clone, PartialEq, Deserialize)]
    #[serde(untagged)]
    pub enum Scalar {
        /// A boolean.
        Bool(bool),
        /// A number.
        Number(f64),
        /// Text.
        Text(String),
    }
}

/// A layer's style.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Style {
    /// Polygons' fill (default none).
    #[serde(default = "none")]
    pub fill: Rgba,
    /// Lines', polygons' outlines' and markers' stroke (default white).
    #[serde(default = "white")]
    pub stroke: Rgba,
    /// Stroke width (default 1.5).
    #[serde(default = "default_width")]
    pub width: f64,
    /// The width's unit (default px).
    #[serde(default = "px")]
    pub unit: Unit,
    /// The whole layer's opacity, 0 … 1.
    #[serde(default = "full")]
    pub opacity: f64,
    /// Dashes: lengths on and off, in the width's unit; empty: solid.
    #[serde(default)]
    pub dash: Vec<f64>,
    /// Markers' radius, in the width's unit (default 3 × the width).
    #[serde(default)]
    pub marker: Option<f64>,
    /// Rules on properties.
    #[serde(default, rename = "rule")]
    pub rules: Vec<Rule>,
}

fn none() -> Rgba {
    Rgba::NONE
}
fn white() -> Rgba {
    Rgba([255, 255, 255, 255])
}
fn default_width() -> f64 {
    1.5
}
fn px() -> Unit {
    Unit::Px
}
fn full() -> f64 {
    1.0
}

impl Default for Style {
    fn default() -> Self {
        Style {
            fill: none(),
            stroke: white(),
            width: default_width(),
            unit: px(),
            opacity: 1.0,
            dash: Vec::new(),
            marker: None,
            rules: Vec::new(),
        }
    }
}

/// What one feature is drawn with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Look {
    /// Fill.
    pub fill: Rgba,
    /// Stroke.
    pub stroke: Rgba,
    /// Stroke width, in the style's unit.
    pub width: f64,
}

/// A palette for features coloured by a property's value (distinct, legible over terrain).
const PALETTE: [[u8; 3]; 10] = [
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [240, 228, 66],
    [0, 114, 178],
    [213, 94, 0],
    [204, 121, 167],
    [153, 153, 153],
    [117, 112, 179],
    [102, 166, 30],
];

impl Style {
    /// Out-of-range settings, in words.
    pub fn check(&self) -> Result<(), String> {
        let finite_pos = |v: f64| v.is_finite() && v >= 0.0;
        if !(finite_pos(self.width) && self.width <= 1e7) {
            return Err(format!("width {} must be 0 … 10⁷", self.width));
        }
        if !(0.0..=1.0).contains(&self.opacity) {
            return Err(format!("opacity {} must be 0 … 1", self.opacity));
        }
        if !self.dash.is_empty()
            && (!self.dash.len().is_multiple_of(2)
                || self.dash.iter().any(|&d| !finite_pos(d) || d > 1e7)
                || self.dash.iter().sum::<f64>() <= 0.0)
        {
            return Err("dash must be pairs of lengths on and off, ≥ 0, not all 0".into());
        }
        if let Some(m) = self.marker
            && !(finite_pos(m) && m <= 1e7)
        {
            return Err(format!("marker {m} must be 0 … 10⁷"));
        }
        for r in &self.rules {
            if let Some(w) = r.width
                && !(finite_pos(w) && w <= 1e7)
            {
                return Err(format!(
                    "rule on `{}`: width {w} must be 0 … 10⁷",
                    r.property
                ));
            }
        }
        Ok(())
    }

    /// What `f` is drawn with.
    pub fn look(&self, f: &Feature) -> Look {
        let mut look = Look {
            fill: self.fill,
            stroke: self.stroke,
            width: self.width,
        };
        for r in &self.rules {
            let Some(v) = f.properties.get(&r.property) else {
                continue;
            };
            let matched = match (&r.equals, v) {
                (None, Value::Null) => false,
                (None, _) => true,
                (Some(toml_value::Scalar::Text(a)), Value::Text(b)) => a == b,
                (Some(toml_value::Scalar::Number(a)), Value::Number(b)) => a == b,
                (Some(toml_value::Scalar::Bool(a)), Value::Bool(b)) => a == b,
                (Some(toml_value::Scalar::Text(a)), Value::Number(b)) => a == &b.to_string(),
                _ => false,
            };
            if !matched {
                continue;
            }
            if r.equals.is_none() {
                // colour by value: the palette, keeping the rule's (or style's) alpha
                let [r0, g0, b0] = PALETTE[(fnv(&v.to_string()) % PALETTE.len() as u64) as usize];
                let fill_a = r.fill.unwrap_or(look.fill).0[3];
                let stroke_a = r.stroke.unwrap_or(look.stroke).0[3];
                if fill_a > 0 {
                    look.fill = Rgba([r0, g0, b0, fill_a]);
                }
                if r.stroke.is_some() {
                    look.stroke = Rgba([r0, g0, b0, stroke_a]);
                }
            } else {
                look.fill = r.fill.unwrap_or(look.fill);
                look.stroke = r.stroke.unwrap_or(look.stroke);
            }
            look.width = r.width.unwrap_or(look.width);
            break;
        }
        look
    }
}

/// FNV-1a, a stable hash for palette picks.
fn fnv(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    #[test]
    fn colours_parse_and_rules_pick_looks() {
        assert_eq!(Rgba::parse("#ff8000").expect("c"), Rgba([255, 128, 0, 255]));
        assert_eq!(
            Rgba::parse("#ff800080").expect("c"),
            Rgba([255, 128, 0, 128])
        );
        assert_eq!(Rgba::parse("#fff").expect("c"), Rgba([255, 255, 255, 255]));
        assert_eq!(Rgba::parse("none").expect("c"), Rgba::NONE);
        for bad in ["red", "#12345", "#gg0000", "#ffé0000", ""] {
            assert!(Rgba::parse(bad).is_err(), "{bad}");
        }
        let style = Style {
            fill: Rgba([1, 2, 3, 100]),
            rules: vec![Rule {
                property: "continent".into(),
                equals: Some(toml_value::Scalar::Text("Europe".into())),
                fill: Some(Rgba([9, 9, 9, 255])),
                stroke: None,
                width: Some(4.0),
            }],
            ..Style::default()
        };
        let f = |c: &str| Feature {
            geometry: crate::Geometry::Points(vec![]),
            properties: BTreeMap::from([("continent".into(), Value::Text(c.into()))]),
        };
        assert_eq!(style.look(&f("Europe")).fill, Rgba([9, 9, 9, 255]));
        assert_eq!(style.look(&f("Europe")).width, 4.0);
        assert_eq!(style.look(&f("Asia")).fill, Rgba([1, 2, 3, 100]));
        assert!(
            Style {
                opacity: 2.0,
                ..Style::default()
            }
            .check()
            .is_err()
        );
        assert!(
            Style {
                dash: vec![1.0],
                ..Style::default()
            }
            .check()
            .is_err()
        );
        assert!(
            Style {
                width: f64::NAN,
                ..Style::default()
            }
            .check()
            .is_err()
        );
    }
}
