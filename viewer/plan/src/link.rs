//! A view as a link: the URL fragment of the browser viewer,
//! `#camera=LAT,LON,ALT,HEADING,PITCH,FOV&shading=lit|none&atmosphere=on|off&renderer=clipmap|cdlod|warp`,
//! with the values and defaults of `sphereclip render` and `view` (`--camera`, `--shading`,
//! `--atmosphere`, `--renderer`), so a link and a command line show the same picture. Written
//! back as the camera moves, so the address bar always holds a link to what is on screen.

use sc_view_space::ViewError;
use sc_view_space::camera::Camera;

/// The camera of a link that names none: `view`'s default (the Atlantic and Africa from 12 000 km).
pub const DEFAULT_CAMERA: &str = "30,10,12000000";

/// The renderers a link may name (`--renderer`); each with its default settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RendererName {
    /// Spherical geometry clipmaps.
    #[default]
    Clipmap,
    /// Icosahedral triangular CDLOD.
    Cdlod,
    /// Geometry-image warping.
    Warp,
}

impl RendererName {
    /// The word in links and on the command line.
    pub fn word(self) -> &'static str {
        match self {
            Self::Clipmap => "clipmap",
            Self::Cdlod => "cdlod",
            Self::Warp => "warp",
        }
    }
}

/// What a link shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewLink {
    /// Where the camera is and where it looks.
    pub camera: Camera,
    /// Lit by the sun (`shading=lit`, the default) or the stored colour exactly (`none`).
    pub lit: bool,
    /// The atmosphere (`atmosphere=on`, the default; drawn only when lit).
    pub atmosphere: bool,
    /// The geometry.
    pub renderer: RendererName,
}

impl ViewLink {
    /// Parses a fragment (with or without its `#`); missing keys take the command line's
    /// defaults, values may be percent-encoded. One line naming the first thing wrong: an unknown
    /// key, a key given twice, a value out of its set.
    pub fn parse(fragment: &str) -> Result<Self, ViewError> {
        let bad = |what: String| ViewError::Camera(format!("the link's {what}"));
        let mut camera = None;
        let mut shading = None;
        let mut atmosphere = None;
        let mut renderer = None;
        let body = fragment.strip_prefix('#').unwrap_or(fragment);
        for part in body.split('&').filter(|p| !p.is_empty()) {
            let (key, raw) = part.split_once('=').unwrap_or((part, ""));
            let value =
                percent_decoded(raw).ok_or_else(|| bad(format!("`{part}` is not UTF-8")))?;
            let slot = match key {
                "camera" => &mut camera,
                "shading" => &mut shading,
                "atmosphere" => &mut atmosphere,
                "renderer" => &mut renderer,
                _ => {
                    return Err(bad(format!(
                        "key `{key}` is not one of camera, shading, atmosphere, renderer"
                    )));
                }
            };
            if slot.replace(value).is_some() {
                return Err(bad(format!("key `{key}` is given twice")));
            }
        }
        let camera = Camera::parse(camera.as_deref().unwrap_or(DEFAULT_CAMERA))
            .map_err(|e| bad(format!("camera: {e}")))?;
        let one_of = |key: &str, v: Option<String>, words: &[&str]| -> Result<usize, ViewError> {
            match v {
                None => Ok(0),
                Some(v) => words
                    .iter()
                    .position(|w| *w == v)
                    .ok_or_else(|| bad(format!("{key} `{v}` is not one of {}", words.join(", ")))),
            }
        };
        let lit = one_of("shading", shading, &["lit", "none"])? == 0;
        let atmosphere = one_of("atmosphere", atmosphere, &["on", "off"])? == 0;
        let renderer = [
            RendererName::Clipmap,
            RendererName::Cdlod,
            RendererName::Warp,
        ][one_of("renderer", renderer, &["clipmap", "cdlod", "warp"])?];
        Ok(Self {
            camera,
            lit,
            atmosphere,
            renderer,
        })
    }

    /// The fragment (with its `#`) of this view: every key, the camera to a centimetre and a
    /// hundredth of a degree (a millionth of a degree in latitude and longitude).
    pub fn fragment(&self) -> String {
        let c = &self.camera;
        format!(
            "#camera={},{},{},{},{},{}&shading={}&atmosphere={}&renderer={}",
            rounded(c.lat_deg, 6),
            rounded(c.lon_deg, 6),
            rounded(c.alt, 2),
            rounded(c.heading, 2),
            rounded(c.pitch, 2),
            rounded(c.fov, 2),
            if self.lit { "lit" } else { "none" },
            if self.atmosphere { "on" } else { "off" },
            self.renderer.word(),
        )
    }
}

/// `v` with at most `places` decimals and no trailing zeros.
fn rounded(v: f64, places: usize) -> String {
    let s = format!("{v:.places$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        &s
    };
    if s == "-0" { "0".into() } else { s.into() }
}

/// `%XX` escapes decoded (a `%` not followed by two hex digits is kept); None if the bytes are
/// not UTF-8.
fn percent_decoded(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match (b[i], b.get(i + 1).copied(), b.get(i + 2).copied()) {
            (b'%', Some(h), Some(l)) if hex(h).is_some() && hex(l).is_some() => {
                out.push((hex(h)? * 16 + hex(l)?) as u8);
                i += 3;
            }
            (c, ..) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_link_takes_the_command_lines_values_and_defaults() {
        let l = ViewLink::parse(
            "#camera=46.5,8,3000,30,-4,60&shading=none&atmosphere=off&renderer=warp",
        )
        .expect("link");
        assert_eq!(
            l.camera,
            Camera::parse("46.5,8,3000,30,-4,60").expect("camera")
        );
        assert!(!l.lit && !l.atmosphere);
        assert_eq!(l.renderer, RendererName::Warp);
        // nothing given: view's start, lit, with air, clipmaps
        let d = ViewLink::parse("").expect("empty");
        assert_eq!(d.camera, Camera::parse(DEFAULT_CAMERA).expect("camera"));
        assert!(d.lit && d.atmosphere);
        assert_eq!(d.renderer, RendererName::Clipmap);
        // the camera's own defaults (pitch from the altitude, heading 0, fov 60), encoded commas
        let e = ViewLink::parse("camera=-89%2C0%2C400000").expect("encoded");
        assert_eq!(e.camera, Camera::parse("-89,0,400000").expect("camera"));
    }

    #[test]
    fn a_bad_link_is_one_line_naming_what_is_wrong() {
        for (link, says) in [
            ("#camera=1,2", "LAT,LON,ALT"),
            ("#camera=95,0,1000", "latitude"),
            ("#shading=flat", "shading `flat`"),
            ("#atmosphere=yes", "atmosphere `yes`"),
            ("#renderer=ray", "renderer `ray`"),
            ("#zoom=3", "key `zoom`"),
            ("#shading=lit&shading=none", "twice"),
            ("#camera=%FF%FE,0,1", "UTF-8"),
        ] {
            let e = ViewLink::parse(link).expect_err(link).to_string();
            assert!(e.contains(says) && !e.contains('\n'), "{link}: {e}");
        }
    }

    #[test]
    fn a_written_link_reads_back_as_the_same_view() {
        let views = [
            "#camera=46.5,8,1.7,30,-4,60&shading=lit&atmosphere=on&renderer=clipmap",
            "#camera=-89.999999,-179.5,400000,359.99,-90,5&shading=none&atmosphere=off&renderer=cdlod",
        ];
        for v in views {
            let l = ViewLink::parse(v).expect(v);
            assert_eq!(l.fragment(), v, "written as read");
            assert_eq!(ViewLink::parse(&l.fragment()).expect("again"), l);
        }
        // a camera between the link's steps comes back within them
        let mut l = ViewLink::parse("").expect("link");
        l.camera.lat_deg = 12.345_678_91;
        l.camera.alt = 1_234.567_89;
        let back = ViewLink::parse(&l.fragment()).expect("back");
        assert!((back.camera.lat_deg - l.camera.lat_deg).abs() <= 5e-7);
        assert!((back.camera.alt - l.camera.alt).abs() <= 5e-3);
        assert_eq!(rounded(-0.0001, 2), "0");
    }
}
