//! The sun, fixed in the world: a direction in the planet's frame (x towards latitude 0,
//! longitude 0; y towards longitude 90° E; z towards the north pole), given by the subsolar point
//! of a UTC time or by an azimuth and elevation seen from a place, and carried into the view
//! space of each frame (viewer at the north pole) where the shader lights the surface.

use crate::ViewError;
use crate::transform::{LocalAxes, Viewer};

/// A unit direction towards the sun in the planet's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sun(pub [f64; 3]);

/// The unit vector of a point of the sphere at `lat`, `lon` (degrees).
pub fn unit_of(lat_deg: f64, lon_deg: f64) -> [f64; 3] {
    LocalAxes::at(lat_deg, lon_deg).up.to_array()
}

impl Sun {
    /// The sun seen from `lat`, `lon` (degrees) at `azimuth` (degrees clockwise from north) and
    /// `elevation` (degrees above the horizon).
    pub fn from_az_el(lat_deg: f64, lon_deg: f64, azimuth_deg: f64, elevation_deg: f64) -> Self {
        let a = LocalAxes::at(lat_deg, lon_deg);
        let (sa, ca) = azimuth_deg.to_radians().sin_cos();
        let (se, ce) = elevation_deg.to_radians().sin_cos();
        Self(((a.north * ca + a.east * sa) * ce + a.up * se).to_array())
    }

    /// The sun at a UTC time (seconds since 1970-01-01T00:00:00Z): straight above its
    /// subsolar point ([`subsolar_point`]).
    pub fn at_unix_time(t: f64) -> Self {
        let (lat, lon) = subsolar_point(t);
        Self(unit_of(lat, lon))
    }

    /// The default sun of a view starting at `lat`, `lon`: 50° above the south-east horizon
    /// there (the north-west of every slope facing it is in shade, the usual map convention
    /// mirrored so that the near side of a globe seen from orbit is lit).
    pub fn default_for(lat_deg: f64, lon_deg: f64) -> Self {
        Self::from_az_el(lat_deg, lon_deg, 135.0, 50.0)
    }

    /// Azimuth and elevation (degrees) of the sun seen from `lat`, `lon`.
    pub fn az_el_at(&self, lat_deg: f64, lon_deg: f64) -> (f64, f64) {
        let (sn, se, su) = self.along(&LocalAxes::at(lat_deg, lon_deg));
        (
            se.atan2(sn).to_degrees().rem_euclid(360.0),
            su.clamp(-1.0, 1.0).asin().to_degrees(),
        )
    }

    /// The direction's components along a place's north, east and up.
    fn along(&self, a: &LocalAxes) -> (f64, f64, f64) {
        let s = glam::DVec3::from_array(self.0);
        (s.dot(a.north), s.dot(a.east), s.dot(a.up))
    }

    /// The direction in the view space of `viewer` (viewer at the north pole: its local north,
    /// east and up are (−o, 0, 0), (0, o, 0) and (0, 0, 1) with `o` = [`Viewer::orient`], the
    /// axes the camera is placed with), as the shader takes it.
    pub fn in_view(&self, viewer: &Viewer) -> [f32; 3] {
        let lat = 90.0 - viewer.colat_rad.to_degrees();
        let lon = viewer.lon_rad.to_degrees();
        let o = viewer.orient();
        let (sn, se, su) = self.along(&LocalAxes::at(lat, lon));
        [(-o * sn) as f32, (o * se) as f32, su as f32]
    }
}

/// The sun's azimuth (degrees clockwise from north) and elevation (degrees above the horizon)
/// as seen from a place not yet known: `--sun`, placed by [`SunAngles::seen_from`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunAngles {
    /// Degrees clockwise from north.
    pub azimuth_deg: f64,
    /// Degrees above the horizon, −90..90.
    pub elevation_deg: f64,
}

impl SunAngles {
    /// Parses `AZIMUTH,ELEVATION` (degrees).
    pub fn parse(s: &str) -> Result<Self, ViewError> {
        let bad = || {
            ViewError::Camera(format!(
                "expected the sun as AZIMUTH,ELEVATION in degrees (elevation −90..90), found `{s}`"
            ))
        };
        let v: Vec<f64> = s
            .split(',')
            .map(|x| x.trim().parse::<f64>().map_err(|_| bad()))
            .collect::<Result<_, _>>()?;
        match v[..] {
            [az, el] if az.is_finite() && (-90.0..=90.0).contains(&el) => Ok(Self {
                azimuth_deg: az,
                elevation_deg: el,
            }),
            _ => Err(bad()),
        }
    }

    /// The sun at these angles seen from `lat`, `lon` (degrees).
    pub fn seen_from(&self, lat_deg: f64, lon_deg: f64) -> Sun {
        Sun::from_az_el(lat_deg, lon_deg, self.azimuth_deg, self.elevation_deg)
    }
}

/// The subsolar point (latitude, longitude in degrees) at a UTC time, seconds since the Unix
/// epoch: the sun's declination and the equation of time from the low-precision formulas of the
/// Astronomical Almanac (good to about 0.01° in 1950–2050).
pub fn subsolar_point(t: f64) -> (f64, f64) {
    // days since J2000.0 (2000-01-01T12:00:00 UTC)
    let n = t / 86_400.0 - 10_957.5;
    let mean_lon = (280.460 + 0.985_647_4 * n).rem_euclid(360.0);
    let g = (357.528 + 0.985_600_3 * n).rem_euclid(360.0).to_radians();
    let ecl_lon = (mean_lon + 1.915 * g.sin() + 0.020 * (2.0 * g).sin()).to_radians();
    let obliquity = (23.439 - 0.000_000_4 * n).to_radians();
    let decl = (obliquity.sin() * ecl_lon.sin()).asin();
    let ra = (obliquity.cos() * ecl_lon.sin()).atan2(ecl_lon.cos());
    // Greenwich mean sidereal time, degrees
    let gmst = (280.460_618_37 + 360.985_647_366_29 * n).rem_euclid(360.0);
    let lon = (ra.to_degrees() - gmst + 540.0).rem_euclid(360.0) - 180.0;
    (decl.to_degrees(), lon)
}

/// Parses a UTC date-time `YYYY-MM-DDTHH:MM[:SS[.fff]][Z]` (RFC 3339 in UTC; a space may stand
/// for the T) into seconds since the Unix epoch.
pub fn parse_utc(s: &str) -> Result<f64, ViewError> {
    let bad = || {
        ViewError::Camera(format!(
            "expected a UTC time as YYYY-MM-DDTHH:MM[:SS]Z (e.g. 2026-06-21T12:00:00Z), found `{s}`"
        ))
    };
    let t = s.trim().trim_end_matches(['Z', 'z']);
    let (date, time) = t.split_once(['T', 't', ' ']).ok_or_else(bad)?;
    let d: Vec<i64> = date
        .split('-')
        .map(|x| x.parse().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    let [y, m, day] = d[..] else {
        return Err(bad());
    };
    let hms: Vec<&str> = time.split(':').collect();
    if !(2..=3).contains(&hms.len()) {
        return Err(bad());
    }
    let h: i64 = hms[0].parse().map_err(|_| bad())?;
    let min: i64 = hms[1].parse().map_err(|_| bad())?;
    let sec: f64 = hms
        .get(2)
        .map_or(Ok(0.0), |v| v.parse().map_err(|_| bad()))?;
    let days_in = |y: i64, m: i64| match m {
        2 if (y % 4 == 0 && y % 100 != 0) || y % 400 == 0 => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    };
    let ok = (1..=12).contains(&m)
        && (1..=days_in(y, m)).contains(&day)
        && (0..24).contains(&h)
        && (0..60).contains(&min)
        && (0.0..61.0).contains(&sec);
    if !ok {
        return Err(bad());
    }
    // days from the civil date (Howard Hinnant's algorithm)
    let (yy, mm) = if m <= 2 { (y - 1, m + 9) } else { (y, m - 3) };
    let era = yy.div_euclid(400);
    let yoe = yy - era * 400;
    let doy = (153 * mm + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    Ok(days as f64 * 86_400.0 + (h * 3600 + min * 60) as f64 + sec)
}

/// Seconds since the Unix epoch as `YYYY-MM-DDTHH:MM:SSZ` (the inverse of [`parse_utc`] to the
/// second).
pub fn format_utc(t: f64) -> String {
    let secs = t.floor() as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // the civil date from days (Howard Hinnant's algorithm)
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transform::offsets_f64;

    #[test]
    fn utc_times_parse_to_unix_seconds() {
        assert_eq!(parse_utc("1970-01-01T00:00:00Z"), Ok(0.0));
        assert_eq!(parse_utc("2000-01-01T12:00Z"), Ok(946_728_000.0));
        assert_eq!(parse_utc("2024-02-29 06:30:15"), Ok(1_709_188_215.0));
        for t in [
            "1970-01-01T00:00:00Z",
            "2024-02-29T06:30:15Z",
            "1969-12-31T23:59:59Z",
            "2100-03-01T12:00:00Z",
        ] {
            assert_eq!(format_utc(parse_utc(t).expect("time")), t);
        }
        for bad in [
            "2023-02-29T00:00Z",
            "2026-13-01T00:00Z",
            "noon",
            "2026-06-21",
        ] {
            assert!(parse_utc(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_subsolar_point_follows_the_seasons_and_the_day() {
        // June solstice 2026 (21 June 08:24 UTC): declination +23.44°; the sun stands over the
        // meridian where it is apparent noon: 15°·(12 h − 8.4 h − EoT), the equation of time
        // then being −1.7 min
        let (lat, lon) = subsolar_point(parse_utc("2026-06-21T08:24:00Z").expect("time"));
        assert!((lat - 23.44).abs() < 0.02, "{lat}");
        assert!((lon - 15.0 * (3.6 + 1.7 / 60.0)).abs() < 0.1, "{lon}");
        // December solstice 2025 (21 December 15:03 UTC)
        let (lat, _) = subsolar_point(parse_utc("2025-12-21T15:03:00Z").expect("time"));
        assert!((lat + 23.44).abs() < 0.02, "{lat}");
        // March equinox 2026 (20 March 14:46 UTC): on the equator
        let (lat, _) = subsolar_point(parse_utc("2026-03-20T14:46:00Z").expect("time"));
        assert!(lat.abs() < 0.02, "{lat}");
    }

    #[test]
    fn bad_sun_positions_are_refused_in_one_line() {
        for bad in ["90", "90,100", "x,10", "10,-91", "nan,10", "1,2,3"] {
            let e = SunAngles::parse(bad).expect_err(bad).to_string();
            assert!(
                e.contains("AZIMUTH,ELEVATION") && !e.contains('\n'),
                "{bad}: {e}"
            );
        }
        let a = SunAngles::parse("270,-5").expect("angles");
        assert_eq!(
            a.seen_from(10.0, 20.0),
            Sun::from_az_el(10.0, 20.0, 270.0, -5.0)
        );
    }

    #[test]
    fn azimuth_and_elevation_round_trip() {
        for (lat, lon, az, el) in [(47.0, 8.0, 135.0, 50.0), (-70.0, 170.0, 10.0, 5.0)] {
            let s = Sun::from_az_el(lat, lon, az, el);
            let (a, e) = s.az_el_at(lat, lon);
            assert!((a - az).abs() < 1e-9 && (e - el).abs() < 1e-9, "{a} {e}");
        }
    }

    /// The view-space direction the shader gets, carried back to the world by the map
    /// transform's f64 twin, is the same world direction for every viewer: the sun does not turn
    /// with the camera.
    #[test]
    fn the_sun_in_view_space_is_the_same_world_direction_for_every_viewer() {
        let sun = Sun::from_az_el(30.0, 40.0, 200.0, 35.0);
        let viewers = [
            (47.0, 8.0),
            (47.5, 8.2),
            (-33.0, 151.0),
            (89.9, 0.0),
            (-89.0, -120.0),
            (0.0, 179.9),
        ];
        for (lat, lon) in viewers {
            let v = Viewer::from_deg(lat, lon);
            let d = sun.in_view(&v).map(f64::from);
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let d = d.map(|x| x / len);
            // the point of the unit sphere in direction d from the centre, as a hemisphere vertex
            let o = offsets_f64(&v, d[0], d[1], 1.0 - d[2], 0.0);
            let back = unit_of(
                90.0 - (v.colat_rad + o.dcolat).to_degrees(),
                (v.lon_rad + o.dlon).to_degrees(),
            );
            for k in 0..3 {
                assert!(
                    (back[k] - sun.0[k]).abs() < 1e-6,
                    "{lat},{lon}: {back:?} vs {:?}",
                    sun.0
                );
            }
        }
    }
}
