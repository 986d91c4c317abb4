//! Vector layers on the sphere (clipmap-data-synthesis §4.1, the image-source graph's vector
//! rasterizer): features read from GeoJSON, FlatGeobuf or Shapefile in pure Rust, their edges
//! following great circles (or rhumb lines, or straight lines in longitude and latitude as GIS
//! tools draw EPSG:4326), prepared once with a spatial index, and rasterized on demand into any
//! window of a longitude × colatitude grid: polygons with exact-area coverage, lines and points
//! stroked with a width in metres or pixels.
//!
//! Angles inside the crate are radians; files hold degrees. No IO but [`read::read_file`].

pub mod coverage;
pub mod edit;
pub mod layer;
pub mod path;
pub mod read;
pub mod style;

use std::collections::BTreeMap;

pub use edit::{EditRule, HeightEdit};
pub use layer::{VectorLayer, Window};
pub use path::Edges;
pub use style::{Rgba, Style};

/// A feature's geometry, degrees of longitude and latitude (WGS 84 read as the sphere's).
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// Points (markers).
    Points(Vec<[f64; 2]>),
    /// Polylines.
    Lines(Vec<Vec<[f64; 2]>>),
    /// Polygons: each its rings, the first the exterior, the others holes.
    Polygons(Vec<Vec<Vec<[f64; 2]>>>),
}

/// A property value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Text.
    Text(String),
    /// A number.
    Number(f64),
    /// True or false.
    Bool(bool),
    /// No value.
    Null,
}

impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Text(s) => f.write_str(s),
            Value::Number(n) => write!(f, "{n}"),
            Value::Bool(b) => write!(f, "{b}"),
            Value::Null => f.write_str(""),
        }
    }
}

/// One feature: a geometry and its properties.
#[derive(Debug, Clone, PartialEq)]
pub struct Feature {
    /// Where it is.
    pub geometry: Geometry,
    /// What it is.
    pub properties: BTreeMap<String, Value>,
}

impl Feature {
    /// What the feature is called: its `name` property (any case), else the first text one.
    pub fn label(&self) -> Option<String> {
        self.properties
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case("name"))
            .or_else(|| {
                self.properties
                    .iter()
                    .find(|(_, v)| matches!(v, Value::Text(s) if !s.is_empty()))
            })
            .map(|(_, v)| v.to_string())
    }
}

/// Why vector data could not be read or used.
#[derive(Debug, thiserror::Error)]
pub enum VectorError {
    /// The file could not be read.
    #[error("cannot read {path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The data is not what a layer can use.
    #[error("{0}")]
    Invalid(String),
}
