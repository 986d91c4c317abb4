//! Reading features: GeoJSON (RFC 7946), FlatGeobuf and ESRI Shapefile, in pure Rust. Files are
//! untrusted: sizes are bounded, coordinates checked, and a reader that panics on malformed
//! bytes is an error naming the file.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

use crate::{Feature, Geometry, Value, VectorError};

/// Largest vector file read, bytes.
pub const MAX_FILE_BYTES: u64 = 2 << 30;

/// Most vertices a layer may hold (before densification).
pub const MAX_VERTICES: usize = 64_000_000;

/// The formats read, by file name extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `.geojson`, `.json`.
    GeoJson,
    /// `.fgb`.
    FlatGeobuf,
    /// `.shp` (with its `.dbf` beside it for properties).
    Shapefile,
}

impl Format {
    /// The format of `path`, by its extension.
    pub fn of(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "geojson" | "json" => Some(Format::GeoJson),
            "fgb" => Some(Format::FlatGeobuf),
            "shp" => Some(Format::Shapefile),
            _ => None,
        }
    }
}

#[cfg_attr(target_arch = "wasm32", allow(dead_code))]
fn err(path: &Path, reason: impl std::fmt::Display) -> VectorError {
    VectorError::Read {
        path: path.display().to_string(),
        reason: reason.to_string(),
    }
}

/// Reads the features of `path` (GeoJSON, FlatGeobuf or Shapefile, by extension). The file must
/// be a regular file (not a symbolic link); a Shapefile's `.dbf` and `.prj` beside it are read
/// when present, and a `.prj` that is not geographic is refused.
#[cfg(not(target_arch = "wasm32"))]
pub fn read_file(path: &Path) -> Result<Vec<Feature>, VectorError> {
    let format = Format::of(path).ok_or_else(|| {
        err(
            path,
            "unknown vector format (use .geojson, .json, .fgb or .shp)",
        )
    })?;
    let read = |p: &Path| sc_store::files::read_regular(p, MAX_FILE_BYTES).map_err(|e| err(p, e));
    let bytes = read(path)?;
    let features = match format {
        Format::GeoJson => from_geojson(&bytes).map_err(|e| err(path, e))?,
        Format::FlatGeobuf => from_flatgeobuf(&bytes).map_err(|e| err(path, e))?,
        Format::Shapefile => {
            let beside = |ext: &str| {
                let p = path.with_extension(ext);
                let upper = path.with_extension(ext.to_ascii_uppercase());
                [p, upper].into_iter().find(|p| p.exists())
            };
            let dbf = beside("dbf").map(|p| read(&p)).transpose()?;
            if let Some(prj) = beside("prj") {
                let text = read(&prj)?;
                check_geographic_wkt(&String::from_utf8_lossy(&text)).map_err(|e| err(&prj, e))?;
            }
            from_shapefile(&bytes, dbf.as_deref()).map_err(|e| err(path, e))?
        }
    };
    check(&features).map_err(|e| err(path, e))?;
    Ok(features)
}

#[cfg_attr(target_arch = "wasm32", allow(dead_code))]
/// A `.prj` must describe longitude and latitude (a GEOGCS), not a projection.
fn check_geographic_wkt(wkt: &str) -> Result<(), String> {
    let t = wkt.trim_start().to_ascii_uppercase();
    if t.starts_with("PROJCS") || t.starts_with("PROJCRS") {
        return Err(
            "the layer is projected; vector layers must be in longitude and latitude (EPSG:4326): reproject it first, e.g. ogr2ogr -t_srs EPSG:4326".into(),
        );
    }
    Ok(())
}

#[cfg_attr(target_arch = "wasm32", allow(dead_code))]
/// Every coordinate finite and within ±180° (longitude, with a little slack) and ±90°; not too
/// many vertices.
fn check(features: &[Feature]) -> Result<(), String> {
    let mut n = 0usize;
    let mut bad = None;
    let mut visit = |p: &[f64; 2]| {
        n += 1;
        if !(p[0].is_finite() && p[1].is_finite() && p[0].abs() <= 540.0 && p[1].abs() <= 90.0)
            && bad.is_none()
        {
            bad = Some(*p);
        }
    };
    for f in features {
        match &f.geometry {
            Geometry::Points(p) => p.iter().for_each(&mut visit),
            Geometry::Lines(l) => l.iter().flatten().for_each(&mut visit),
            Geometry::Polygons(p) => p.iter().flatten().flatten().for_each(&mut visit),
        }
    }
    if let Some(p) = bad {
        return Err(format!(
            "coordinate ({}, {}) is not a longitude and latitude in degrees (the layer must be in EPSG:4326)",
            p[0], p[1]
        ));
    }
    if n > MAX_VERTICES {
        return Err(format!(
            "{n} vertices, more than the {MAX_VERTICES} a layer may hold"
        ));
    }
    Ok(())
}

/// Runs a third-party reader on untrusted bytes: a panic is an error.
fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
        .unwrap_or_else(|_| Err(format!("malformed {what} (its reader failed)")))
}

/// The features of GeoJSON text: a FeatureCollection, a Feature or a bare geometry.
pub fn from_geojson(bytes: &[u8]) -> Result<Vec<Feature>, String> {
    guarded("GeoJSON", || {
        let text = std::str::from_utf8(bytes).map_err(|_| "not UTF-8 text".to_string())?;
        let gj: geojson::GeoJson = text.parse().map_err(|e| format!("not GeoJSON: {e}"))?;
        let mut out = Vec::new();
        match gj {
            geojson::GeoJson::FeatureCollection(fc) => {
                for f in fc.features {
                    push_geojson_feature(f, &mut out);
                }
            }
            geojson::GeoJson::Feature(f) => push_geojson_feature(f, &mut out),
            geojson::GeoJson::Geometry(g) => push_geometry(&g.value, BTreeMap::new(), &mut out),
        }
        Ok(out)
    })
}

fn push_geojson_feature(f: geojson::Feature, out: &mut Vec<Feature>) {
    let properties = f
        .properties
        .map(|p| {
            p.into_iter()
                .map(|(k, v)| (k, json_value(v)))
                .collect::<BTreeMap<_, _>>()
        })
        .unwrap_or_default();
    if let Some(g) = f.geometry {
        push_geometry(&g.value, properties, out);
    }
}

fn json_value(v: serde_json::Value) -> Value {
    match v {
        serde_json::Value::String(s) => Value::Text(s),
        serde_json::Value::Number(n) => n.as_f64().map_or(Value::Null, Value::Number),
        serde_json::Value::Bool(b) => Value::Bool(b),
        serde_json::Value::Null => Value::Null,
        other => Value::Text(other.to_string()),
    }
}

fn xy(p: &geojson::Position) -> [f64; 2] {
    let p = p.as_slice();
    [
        p.first().copied().unwrap_or(f64::NAN),
        p.get(1).copied().unwrap_or(f64::NAN),
    ]
}

/// A GeoJSON geometry as features (a collection's members become features of their own, with
/// the same properties).
fn push_geometry(
    g: &geojson::GeometryValue,
    properties: BTreeMap<String, Value>,
    out: &mut Vec<Feature>,
) {
    use geojson::GeometryValue as G;
    let ring = |r: &[geojson::Position]| r.iter().map(xy).collect::<Vec<_>>();
    let poly = |p: &[Vec<geojson::Position>]| p.iter().map(|r| ring(r)).collect::<Vec<_>>();
    let geometry = match g {
        G::Point { coordinates } => Geometry::Points(vec![xy(coordinates)]),
        G::MultiPoint { coordinates } => Geometry::Points(ring(coordinates)),
        G::LineString { coordinates } => Geometry::Lines(vec![ring(coordinates)]),
        G::MultiLineString { coordinates } => {
            Geometry::Lines(coordinates.iter().map(|l| ring(l)).collect())
        }
        G::Polygon { coordinates } => Geometry::Polygons(vec![poly(coordinates)]),
        G::MultiPolygon { coordinates } => {
            Geometry::Polygons(coordinates.iter().map(|p| poly(p)).collect())
        }
        G::GeometryCollection { geometries } => {
            for g in geometries {
                push_geometry(&g.value, properties.clone(), out);
            }
            return;
        }
    };
    out.push(Feature {
        geometry,
        properties,
    });
}

/// The features of a FlatGeobuf file's bytes.
pub fn from_flatgeobuf(bytes: &[u8]) -> Result<Vec<Feature>, String> {
    use flatgeobuf::{FallibleStreamingIterator, FeatureProperties, FgbReader};
    use geozero::ToJson;
    guarded("FlatGeobuf", || {
        let reader =
            FgbReader::open(Cursor::new(bytes)).map_err(|e| format!("not FlatGeobuf: {e}"))?;
        if let Some(crs) = reader.header().crs() {
            let code = crs.code();
            if code != 0 && code != 4326 && code != 4979 && code != 4269 {
                return Err(format!(
                    "the layer is in EPSG:{code}; vector layers must be in longitude and latitude (EPSG:4326): reproject it first, e.g. ogr2ogr -t_srs EPSG:4326"
                ));
            }
        }
        let mut iter = reader
            .select_all_seq()
            .map_err(|e| format!("cannot read its features: {e}"))?;
        let mut out = Vec::new();
        while let Some(f) = iter.next().map_err(|e| format!("a feature: {e}"))? {
            let json = f.to_json().map_err(|e| format!("a geometry: {e}"))?;
            let g: geojson::Geometry = json.parse().map_err(|e| format!("a geometry: {e}"))?;
            let properties = f
                .properties()
                .map_err(|e| format!("properties: {e}"))?
                .into_iter()
                .map(|(k, v)| {
                    let v = v
                        .parse::<f64>()
                        .map(Value::Number)
                        .unwrap_or(Value::Text(v));
                    (k, v)
                })
                .collect();
            push_geometry(&g.value, properties, &mut out);
        }
        Ok(out)
    })
}

/// The features of a Shapefile (`.shp` bytes, and its `.dbf`'s when there is one).
pub fn from_shapefile(shp: &[u8], dbf: Option<&[u8]>) -> Result<Vec<Feature>, String> {
    use shapefile::dbase::FieldValue as F;
    guarded("Shapefile", || {
        let mut shapes = shapefile::ShapeReader::new(Cursor::new(shp))
            .map_err(|e| format!("not a Shapefile: {e}"))?;
        let shapes: Vec<shapefile::Shape> = shapes
            .iter_shapes()
            .collect::<Result<_, _>>()
            .map_err(|e| format!("a shape: {e}"))?;
        let mut records = Vec::new();
        if let Some(dbf) = dbf {
            let mut r = shapefile::dbase::Reader::new(Cursor::new(dbf))
                .map_err(|e| format!("its .dbf: {e}"))?;
            for rec in r.iter_records() {
                let rec = rec.map_err(|e| format!("its .dbf: {e}"))?;
                let props: BTreeMap<String, Value> = rec
                    .into_iter()
                    .map(|(k, v)| {
                        let v = match v {
                            F::Character(Some(s)) | F::Memo(s) => Value::Text(s),
                            F::Numeric(Some(n)) | F::Currency(n) | F::Double(n) => Value::Number(n),
                            F::Float(Some(n)) => Value::Number(f64::from(n)),
                            F::Integer(n) => Value::Number(f64::from(n)),
                            F::Logical(Some(b)) => Value::Bool(b),
                            _ => Value::Null,
                        };
                        (k, v)
                    })
                    .collect();
                records.push(props);
            }
        }
        let mut out = Vec::new();
        for (i, s) in shapes.into_iter().enumerate() {
            let properties = records.get(i).cloned().unwrap_or_default();
            if let Some(geometry) = shape_geometry(s) {
                out.push(Feature {
                    geometry,
                    properties,
                });
            }
        }
        Ok(out)
    })
}

fn shape_geometry(s: shapefile::Shape) -> Option<Geometry> {
    use shapefile::{PolygonRing, Shape as S};
    fn pts<P: shapefile::record::traits::HasXY>(v: &[P]) -> Vec<[f64; 2]> {
        v.iter().map(|p| [p.x(), p.y()]).collect()
    }
    fn rings<P: shapefile::record::traits::HasXY>(rs: &[PolygonRing<P>]) -> Geometry {
        // an outer ring starts a polygon; inner rings are its holes
        let mut polys: Vec<Vec<Vec<[f64; 2]>>> = Vec::new();
        for r in rs {
            match r {
                PolygonRing::Outer(p) => polys.push(vec![pts(p)]),
                PolygonRing::Inner(p) => match polys.last_mut() {
                    Some(poly) => poly.push(pts(p)),
                    None => polys.push(vec![pts(p)]),
                },
            }
        }
        Geometry::Polygons(polys)
    }
    Some(match s {
        S::NullShape | S::Multipatch(_) => return None,
        S::Point(p) => Geometry::Points(vec![[p.x, p.y]]),
        S::PointM(p) => Geometry::Points(vec![[p.x, p.y]]),
        S::PointZ(p) => Geometry::Points(vec![[p.x, p.y]]),
        S::Multipoint(m) => Geometry::Points(pts(m.points())),
        S::MultipointM(m) => Geometry::Points(pts(m.points())),
        S::MultipointZ(m) => Geometry::Points(pts(m.points())),
        S::Polyline(l) => Geometry::Lines(l.parts().iter().map(|p| pts(p)).collect()),
        S::PolylineM(l) => Geometry::Lines(l.parts().iter().map(|p| pts(p)).collect()),
        S::PolylineZ(l) => Geometry::Lines(l.parts().iter().map(|p| pts(p)).collect()),
        S::Polygon(p) => rings(p.rings()),
        S::PolygonM(p) => rings(p.rings()),
        S::PolygonZ(p) => rings(p.rings()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geojson_features_collections_and_bad_input() {
        let fc = br#"{"type":"FeatureCollection","features":[
            {"type":"Feature","properties":{"name":"a","n":3},"geometry":{"type":"Polygon","coordinates":[[[0,0],[1,0],[1,1],[0,0]]]}},
            {"type":"Feature","properties":null,"geometry":{"type":"GeometryCollection","geometries":[
                {"type":"Point","coordinates":[5,6]},{"type":"LineString","coordinates":[[0,0],[2,2]]}]}}]}"#;
        let f = from_geojson(fc).expect("reads");
        assert_eq!(f.len(), 3);
        assert_eq!(f[0].label().as_deref(), Some("a"));
        assert_eq!(f[0].properties["n"], Value::Number(3.0));
        assert_eq!(f[1].geometry, Geometry::Points(vec![[5.0, 6.0]]));
        for bad in [
            &b"{"[..],
            b"\xff\xfe",
            b"{\"type\":\"Polygon\",\"coordinates\":7}",
            b"",
        ] {
            assert!(from_geojson(bad).is_err());
        }
        assert!(from_shapefile(b"not a shapefile at all", None).is_err());
        assert!(from_flatgeobuf(b"fgb\x03fgb\x00garbage").is_err());
        let far = Feature {
            geometry: Geometry::Points(vec![[600000.0, 5.0e6]]),
            properties: BTreeMap::new(),
        };
        assert!(check(&[far]).expect_err("projected").contains("EPSG:4326"));
        assert!(check_geographic_wkt("PROJCS[\"UTM\"]").is_err());
        assert!(check_geographic_wkt("GEOGCS[\"WGS 84\"]").is_ok());
    }
}
