//! Finding a place: a latitude and longitude typed in the usual forms (decimal, degrees with
//! minutes and seconds, signs or N/S/E/W), or a name looked up in a gazetteer with forgiving
//! matching (case, accents, a letter missing or wrong).
//!
//! The gazetteer is text, one place a line: `name TAB ascii-name TAB country TAB lat TAB lon TAB
//! population` (`samples/gazetteer.tsv`, GeoNames' places of 5000 people or more); lines starting
//! with `#` are comments.

use crate::ViewError;

/// A place found.
#[derive(Debug, Clone, PartialEq)]
pub struct Place {
    /// The place's name and country ("Zermatt, Switzerland"), or the coordinates as typed.
    pub label: String,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees (−180..180).
    pub lon_deg: f64,
}

/// One gazetteer entry.
#[derive(Debug, Clone)]
struct Entry {
    name: String,
    /// Lower case, accents removed: what queries are compared with.
    key: String,
    country: String,
    lat: f64,
    lon: f64,
    population: u64,
}

/// Places by name.
#[derive(Debug, Clone, Default)]
pub struct Gazetteer {
    entries: Vec<Entry>,
}

/// Lower case without accents (by the ASCII name the gazetteer gives, or a fold of the common
/// Latin letters for what is typed).
fn fold(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars().flat_map(char::to_lowercase) {
        let plain = match c {
            'à' | 'á' | 'â' | 'ã' | 'ä' | 'å' | 'ā' | 'ă' | 'ą' => "a",
            'æ' => "ae",
            'ç' | 'ć' | 'č' | 'ĉ' => "c",
            'ď' | 'đ' => "d",
            'è' | 'é' | 'ê' | 'ë' | 'ē' | 'ė' | 'ę' | 'ě' => "e",
            'ğ' | 'ĝ' | 'ģ' => "g",
            'ì' | 'í' | 'î' | 'ï' | 'ī' | 'į' | 'ı' => "i",
            'ł' | 'ľ' | 'ĺ' | 'ļ' => "l",
            'ñ' | 'ń' | 'ň' | 'ņ' => "n",
            'ò' | 'ó' | 'ô' | 'õ' | 'ö' | 'ø' | 'ō' | 'ő' => "o",
            'œ' => "oe",
            'ř' | 'ŕ' => "r",
            'ś' | 'š' | 'ş' | 'ș' => "s",
            'ß' => "ss",
            'ť' | 'ţ' | 'ț' => "t",
            'ù' | 'ú' | 'û' | 'ü' | 'ū' | 'ů' | 'ű' | 'ų' => "u",
            'ý' | 'ÿ' => "y",
            'ź' | 'ż' | 'ž' => "z",
            '-' | '\'' | '’' | '.' => " ",
            c => {
                out.push(c);
                continue;
            }
        };
        out.push_str(plain);
    }
    out.split_whitespace().collect::<Vec<_>>().join(" ")
}

impl Gazetteer {
    /// Reads the gazetteer's text; a line that does not parse is an error naming it.
    pub fn parse(text: &str) -> Result<Self, ViewError> {
        let mut entries = Vec::new();
        for (i, line) in text.lines().enumerate() {
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let bad = || ViewError::Camera(format!("gazetteer line {}: `{line}`", i + 1));
            let f: Vec<&str> = line.split('\t').collect();
            let [name, ascii, country, lat, lon, pop] = f[..] else {
                return Err(bad());
            };
            let (lat, lon) = (
                lat.parse::<f64>().map_err(|_| bad())?,
                lon.parse::<f64>().map_err(|_| bad())?,
            );
            if !(-90.0..=90.0).contains(&lat) || !(-180.0..=180.0).contains(&lon) || name.is_empty()
            {
                return Err(bad());
            }
            entries.push(Entry {
                name: name.to_string(),
                key: fold(if ascii.is_empty() { name } else { ascii }),
                country: country.to_string(),
                lat,
                lon,
                population: pop.parse().map_err(|_| bad())?,
            });
        }
        Ok(Self { entries })
    }

    /// How many places it holds.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Up to `n` places whose names match `query`, best first: the whole name, then names that
    /// start with it, then names a few letters away (a letter missing, extra, wrong or two
    /// swapped); among equals the more populous. `NAME, COUNTRY` keeps the places of countries
    /// whose name starts with COUNTRY.
    pub fn search(&self, query: &str, n: usize) -> Vec<Place> {
        let (name, country) = match query.split_once(',') {
            Some((a, b)) => (fold(a), Some(fold(b))),
            None => (fold(query), None),
        };
        if name.is_empty() {
            return Vec::new();
        }
        let len = name.chars().count();
        let mut scored: Vec<(f64, &Entry)> = self
            .entries
            .iter()
            .filter(|e| {
                country
                    .as_deref()
                    .is_none_or(|c| fold(&e.country).starts_with(c))
            })
            .filter_map(|e| {
                let score = if e.key == name {
                    3.0
                } else if e.key.starts_with(&name) {
                    2.0 + len as f64 / e.key.chars().count() as f64
                } else {
                    // only names of about the query's length can be a few letters away
                    let l = e.key.chars().count();
                    if l.abs_diff(len) > 2 {
                        return None;
                    }
                    let d = strsim::damerau_levenshtein(&e.key, &name);
                    let allowed = if len <= 4 { 1 } else { 2 };
                    if d > allowed {
                        return None;
                    }
                    1.0 - d as f64 / l.max(len) as f64
                };
                Some((score + (e.population.max(1) as f64).log10() / 100.0, e))
            })
            .collect();
        scored.sort_by(|a, b| b.0.total_cmp(&a.0));
        scored
            .into_iter()
            .take(n)
            .map(|(_, e)| Place {
                label: format!("{}, {}", e.name, e.country),
                lat_deg: e.lat,
                lon_deg: e.lon,
            })
            .collect()
    }

    /// What `query` names: coordinates ([`parse_lat_lon`]) if it is some, else the best match
    /// among the places; an error saying why when neither.
    pub fn find(&self, query: &str) -> Result<Place, ViewError> {
        if let Some(p) = parse_lat_lon(query)? {
            return Ok(p);
        }
        self.search(query, 1).into_iter().next().ok_or_else(|| {
            ViewError::Camera(format!(
                "no place called `{}` among {} places, and not a latitude and longitude",
                query.trim(),
                self.len()
            ))
        })
    }
}

/// One coordinate's parts: up to three numbers (degrees, minutes, seconds), a sign, a
/// hemisphere letter.
#[derive(Debug, Default)]
struct Part {
    numbers: Vec<f64>,
    negative: bool,
    hemi: Option<char>,
}

impl Part {
    fn value(&self, s: &str) -> Result<f64, ViewError> {
        let bad = |why: &str| ViewError::Camera(format!("`{}`: {why}", s.trim()));
        let (d, m, sec) = match self.numbers[..] {
            [d] => (d, 0.0, 0.0),
            [d, m] => (d, m, 0.0),
            [d, m, s] => (d, m, s),
            _ => return Err(bad("expected degrees, minutes and seconds at most")),
        };
        if self.numbers.len() > 1 && (d.fract() != 0.0 || d < 0.0) {
            return Err(bad("degrees with minutes must be whole"));
        }
        if !(0.0..60.0).contains(&m) || !(0.0..60.0).contains(&sec) {
            return Err(bad("minutes and seconds must be 0..60"));
        }
        if self.numbers.len() == 3 && m.fract() != 0.0 {
            return Err(bad("minutes with seconds must be whole"));
        }
        let v = d.abs() + m / 60.0 + sec / 3600.0;
        let south_west = matches!(self.hemi, Some('S' | 'W'));
        if (self.negative || d < 0.0) && self.hemi.is_some() {
            return Err(bad("a sign and a hemisphere letter together"));
        }
        Ok(if self.negative || d < 0.0 || south_west {
            -v
        } else {
            v
        })
    }
}

/// A token of typed coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Token {
    /// A number: its value (unsigned), whether a minus sign led it, and whether a degree mark
    /// followed it.
    Number(f64, bool, bool),
    /// N, S, E or W.
    Hemi(char),
    /// A comma or semicolon.
    Sep,
}

/// `s` as tokens (unit marks other than degrees dropped); `None` when it holds anything else.
fn tokens(s: &str) -> Option<Vec<Token>> {
    let mut out = Vec::new();
    let mut chars = s.chars().peekable();
    while let Some(&c) = chars.peek() {
        match c {
            ',' | ';' => {
                chars.next();
                out.push(Token::Sep);
            }
            c if c.is_whitespace() => {
                chars.next();
            }
            '°' | 'º' => {
                chars.next();
                match out.last_mut() {
                    Some(Token::Number(_, _, deg)) if !*deg => *deg = true,
                    _ => return None,
                }
            }
            '\'' | '′' | '’' | '"' | '″' | '”' => {
                chars.next();
                if !matches!(out.last(), Some(Token::Number(..))) {
                    return None;
                }
            }
            'N' | 'S' | 'E' | 'W' | 'n' | 's' | 'e' | 'w' => {
                chars.next();
                out.push(Token::Hemi(c.to_ascii_uppercase()));
            }
            '-' | '+' | '0'..='9' | '.' => {
                let mut t = String::new();
                while let Some(&d) = chars.peek() {
                    if d.is_ascii_digit() || d == '.' || ((d == '-' || d == '+') && t.is_empty()) {
                        t.push(d);
                        chars.next();
                    } else {
                        break;
                    }
                }
                let v: f64 = t.trim_start_matches(['-', '+']).parse().ok()?;
                out.push(Token::Number(v, t.starts_with('-'), false));
            }
            _ => return None,
        }
    }
    Some(out)
}

/// Splits `s` into coordinate parts. With hemisphere letters or a comma, parts end at a comma
/// and at a letter after numbers (a letter before numbers starts one); without, each number
/// marked with ° starts a part, and with no marks each number is one. `None` when `s` holds
/// anything but numbers, marks, letters N/S/E/W and separators.
fn parts(s: &str) -> Option<Vec<Part>> {
    let t = tokens(s)?;
    let mut out: Vec<Part> = Vec::new();
    let mut cur = Part::default();
    let flush = |cur: &mut Part, out: &mut Vec<Part>| {
        if !cur.numbers.is_empty() || cur.hemi.is_some() {
            out.push(std::mem::take(cur));
        }
    };
    let delimited = t.iter().any(|x| matches!(x, Token::Hemi(_) | Token::Sep));
    let marked = t.iter().any(|x| matches!(x, Token::Number(_, _, true)));
    for x in t {
        match x {
            Token::Sep => flush(&mut cur, &mut out),
            Token::Hemi(h) => {
                if cur.numbers.is_empty() {
                    if cur.hemi.is_some() {
                        return None;
                    }
                    cur.hemi = Some(h);
                } else if cur.hemi.is_some() {
                    flush(&mut cur, &mut out);
                    cur.hemi = Some(h);
                } else {
                    cur.hemi = Some(h);
                    flush(&mut cur, &mut out);
                }
            }
            Token::Number(v, negative, degrees) => {
                let starts = if delimited {
                    false
                } else if marked {
                    degrees
                } else {
                    true
                };
                if starts {
                    flush(&mut cur, &mut out);
                }
                if cur.numbers.is_empty() {
                    cur.negative = negative;
                } else if negative {
                    return None;
                }
                cur.numbers.push(v);
            }
        }
    }
    flush(&mut cur, &mut out);
    Some(out)
}

/// A latitude and longitude typed as people write them: `46.02, 7.75`, `46.02 7.75`,
/// `-17 179.9`, `45°58′N 7°39′E`, `45 58 N 7 39 E`, `N 45° 58.5′ E 7° 39′`, `7.65E 45.97N`.
/// `Ok(None)`: not coordinates at all (a name); `Err`: coordinates that are wrong (out of range,
/// minutes past 60…), saying why.
pub fn parse_lat_lon(s: &str) -> Result<Option<Place>, ViewError> {
    let Some(p) = parts(s) else {
        return Ok(None);
    };
    if p.len() != 2 || p.iter().any(|x| x.numbers.is_empty()) {
        return Ok(None);
    }
    let bad = |why: String| ViewError::Camera(format!("`{}`: {why}", s.trim()));
    let is_lon = |x: &Part| matches!(x.hemi, Some('E' | 'W'));
    let is_lat = |x: &Part| matches!(x.hemi, Some('N' | 'S'));
    let (la, lo) = if is_lon(&p[0]) || is_lat(&p[1]) {
        (&p[1], &p[0])
    } else {
        (&p[0], &p[1])
    };
    if is_lon(la) || is_lat(lo) {
        return Err(bad("one latitude (N/S) and one longitude (E/W)".into()));
    }
    let (lat, lon) = (la.value(s)?, lo.value(s)?);
    if !(-90.0..=90.0).contains(&lat) {
        return Err(bad(format!("latitude {lat} is outside −90..90")));
    }
    if !(-180.0..=360.0).contains(&lon) {
        return Err(bad(format!("longitude {lon} is outside −180..360")));
    }
    let lon = if lon > 180.0 { lon - 360.0 } else { lon };
    Ok(Some(Place {
        label: format!("{lat:.5}, {lon:.5}"),
        lat_deg: lat,
        lon_deg: lon,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(s: &str) -> (f64, f64) {
        let p = parse_lat_lon(s)
            .unwrap_or_else(|e| panic!("{s}: {e}"))
            .unwrap_or_else(|| panic!("{s}: not coordinates"));
        (p.lat_deg, p.lon_deg)
    }

    fn near(a: (f64, f64), b: (f64, f64)) -> bool {
        (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9
    }

    #[test]
    fn coordinates_parse_in_the_usual_forms() {
        let zermatt = (45.0 + 58.0 / 60.0, 7.0 + 39.0 / 60.0);
        for s in [
            "45°58′N 7°39′E",
            "45°58'N, 7°39'E",
            "45 58 N 7 39 E",
            "N 45° 58′ E 7° 39′",
            "7°39′E 45°58′N",
            "45°58′0″N 7°39′0″E",
            "45.966666666666667, 7.65",
        ] {
            assert!(near(at(s), zermatt), "{s}: {:?}", at(s));
        }
        assert!(near(at("-17 179.9"), (-17.0, 179.9)));
        assert!(near(at("-17, -179.9"), (-17.0, -179.9)));
        assert!(near(at("33°51′S 151°12′E"), (-33.85, 151.2)));
        assert!(near(at("40.7 N 74.0 W"), (40.7, -74.0)));
        assert!(near(at("45°58′30″N 7°39′E"), (45.975, 7.65)));
        assert!(near(at("10, 350"), (10.0, -10.0)));
        for name in ["Zermatt", "zermat", "Paris, France", "", "N", "12", "1 2 3"] {
            assert!(
                parse_lat_lon(name).expect("not an error").is_none(),
                "{name}"
            );
        }
        for wrong in ["95, 10", "45°61′N 7°E", "10 N 20 N", "-45 S 7 E", "10, 400"] {
            assert!(parse_lat_lon(wrong).is_err(), "{wrong}");
        }
    }

    fn gazetteer() -> Gazetteer {
        Gazetteer::parse(
            "# name\tascii\tcountry\tlat\tlon\tpopulation\n\
             Zermatt\t\tSwitzerland\t46.01998\t7.74863\t6629\n\
             Zürich\tZurich\tSwitzerland\t47.36667\t8.55\t341730\n\
             Zermeño\tZermeno\tMexico\t20.0\t-100.0\t8000\n\
             Paris\t\tFrance\t48.85341\t2.3488\t2138551\n\
             Paris\t\tUnited States\t33.66094\t-95.55551\t24782\n\
             Parit\t\tMalaysia\t4.5\t100.9\t9000\n",
        )
        .expect("gazetteer")
    }

    #[test]
    fn names_are_found_whole_by_prefix_and_a_letter_off() {
        let g = gazetteer();
        let first = |q: &str| g.search(q, 3).first().map(|p| p.label.clone());
        assert_eq!(first("Zermatt").as_deref(), Some("Zermatt, Switzerland"));
        assert_eq!(first("zermat").as_deref(), Some("Zermatt, Switzerland"));
        assert_eq!(first("zermattt").as_deref(), Some("Zermatt, Switzerland"));
        assert_eq!(first("ZÜRICH").as_deref(), Some("Zürich, Switzerland"));
        assert_eq!(first("zurich").as_deref(), Some("Zürich, Switzerland"));
        assert_eq!(first("zuirch").as_deref(), Some("Zürich, Switzerland"));
        // the more populous of two Parises, unless the country says otherwise
        assert_eq!(first("paris").as_deref(), Some("Paris, France"));
        assert_eq!(
            first("Paris, united").as_deref(),
            Some("Paris, United States")
        );
        assert!(g.search("qqqqqq", 3).is_empty());
        let p = g.find("45°58′N 7°39′E").expect("coordinates");
        assert!((p.lat_deg - 45.966_666).abs() < 1e-5);
        assert!(g.find("Atlantis").is_err());
        assert!(g.find("95, 10").is_err());
    }

    #[test]
    fn a_broken_gazetteer_line_is_named() {
        let e = Gazetteer::parse("# x\nA\t\tB\t95\t0\t1\n").expect_err("latitude 95");
        assert!(e.to_string().contains("line 2"), "{e}");
        assert!(Gazetteer::parse("A\tB\n").is_err());
    }
}
