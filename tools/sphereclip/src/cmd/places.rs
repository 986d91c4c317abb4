//! The gazetteer the binary carries (`samples/gazetteer.tsv.gz`: GeoNames' places of 5000 people
//! or more, 1.5 MB), read once when a command first looks a place up, and `--goto`.

use std::io::Read;
use std::sync::{Arc, OnceLock};

use anyhow::{Context, Result};
use sc_view_space::camera::Camera;
use sc_view_space::places::Gazetteer;

static GAZETTEER_GZ: &[u8] = include_bytes!("../../../../samples/gazetteer.tsv.gz");

/// The gazetteer (parsed on first use, shared after).
pub fn gazetteer() -> Result<Arc<Gazetteer>> {
    static PLACES: OnceLock<std::result::Result<Arc<Gazetteer>, String>> = OnceLock::new();
    PLACES
        .get_or_init(|| {
            let mut text = String::new();
            flate2::read::GzDecoder::new(GAZETTEER_GZ)
                .read_to_string(&mut text)
                .map_err(|e| format!("the gazetteer does not unpack: {e}"))?;
            Gazetteer::parse(&text)
                .map(Arc::new)
                .map_err(|e| e.to_string())
        })
        .clone()
        .map_err(|e| anyhow::anyhow!("{e}"))
}

/// The camera moved above `place` (a name or coordinates): `camera`'s altitude, heading, pitch
/// and field of view over the place's latitude and longitude; and the place's label.
pub fn goto(camera: Camera, place: &str) -> Result<(Camera, String)> {
    // coordinates need no gazetteer (50 ms to unpack and read)
    let p = match sc_view_space::places::parse_lat_lon(place) {
        Ok(Some(p)) => p,
        Ok(None) => gazetteer()?
            .find(place)
            .with_context(|| format!("--goto {place}"))?,
        Err(e) => return Err(e).with_context(|| format!("--goto {place}")),
    };
    Ok((
        Camera {
            lat_deg: p.lat_deg,
            lon_deg: p.lon_deg,
            ..camera
        },
        p.label,
    ))
}
