//! Line plots of a metric against latitude, as SVG (text, no font or raster dependency, opens in
//! any browser; the report's index.html embeds them).

use std::fmt::Write;

/// One line of a plot.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// (x, y) points; non-finite y values break the line.
    pub points: Vec<(f64, f64)>,
    /// Its colour and dash (indices into the palette and the dash patterns); `None`: by its
    /// place in the plot.
    pub style: Option<(usize, usize)>,
}

/// Where a plot's axes run: `None` for the data's range.
#[derive(Debug, Clone, Copy, Default)]
pub struct Axes {
    /// x from … to, and the tick step.
    pub x: Option<(f64, f64, f64)>,
    /// y from … to.
    pub y: Option<(f64, f64)>,
    /// The most y may reach (a share: 1), when the range is the data's.
    pub y_cap: Option<f64>,
}

impl Axes {
    /// |latitude| from 0 to 90° (ticks every 15°).
    pub const LATITUDE: Axes = Axes {
        x: Some((0.0, 90.0, 15.0)),
        y: None,
        y_cap: None,
    };

    /// |latitude| against a share, up to at most 1.
    pub const LATITUDE_SHARE: Axes = Axes {
        x: Some((0.0, 90.0, 15.0)),
        y: None,
        y_cap: Some(1.0),
    };

    /// |latitude| against a fraction, 0 … 1.
    pub const LATITUDE_FRACTION: Axes = Axes {
        x: Some((0.0, 90.0, 15.0)),
        y: Some((0.0, 1.0)),
        y_cap: None,
    };
}

/// Dash patterns of the series, one per pass through the palette.
const DASHES: [&str; 3] = ["none", "6 3", "2 2"];

const PALETTE: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
];

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// A plot of `series` with a title and axis labels; y from 0 (or the data's minimum if negative)
/// to the data's maximum, x over the points' range.
pub fn svg(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> String {
    svg_on(title, x_label, y_label, series, Axes::default())
}

/// [`svg`] with the axes `axes` gives (the data's range where it gives none).
pub fn svg_on(title: &str, x_label: &str, y_label: &str, series: &[Series], axes: Axes) -> String {
    let (w, h) = (640.0, 360.0);
    let (l, r, t, b) = (70.0, 170.0, 40.0, 50.0);
    let pts = series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|p| p.1.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) =
        (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, f64::NEG_INFINITY);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if !x0.is_finite() || x1 <= x0 {
        (x0, x1) = (0.0, 90.0);
    }
    if !y1.is_finite() || y1 <= y0 {
        y1 = y0 + 1.0;
    }
    // axes on round numbers: ticks at multiples of 1, 2 or 5 × 10^k
    let (mut xstep, mut ystep) = (nice_step(x1 - x0), nice_step((y1 - y0) * 1.05));
    x0 = (x0 / xstep).floor() * xstep;
    x1 = (x1 / xstep).ceil() * xstep;
    y0 = (y0 / ystep).floor() * ystep;
    y1 = ((y1 + (y1 - y0) * 0.05) / ystep).ceil() * ystep;
    if let Some((a, b, step)) = axes.x {
        (x0, x1, xstep) = (a, b, step);
    }
    if let Some((a, b)) = axes.y {
        (y0, y1) = (a, b);
        ystep = nice_step(b - a);
    }
    if let Some(cap) = axes.y_cap
        && y1 > cap
    {
        y1 = cap;
        ystep = nice_step(y1 - y0);
    }
    let px = |x: f64| l + (x - x0) / (x1 - x0) * (w - l - r);
    let py = |y: f64| h - b - (y - y0) / (y1 - y0) * (h - t - b);
    let mut s = String::new();
    let _ = write!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"##
    );
    let _ = write!(s, r##"<rect width="{w}" height="{h}" fill="white"/>"##);
    let _ = write!(
        s,
        r##"<text x="{}" y="22" text-anchor="middle" font-size="14">{}</text>"##,
        (l + w - r) / 2.0,
        esc(title)
    );
    // axes and ticks
    let _ = write!(
        s,
        r##"<path d="M{l} {t} V{} H{}" stroke="black" fill="none"/>"##,
        h - b,
        w - r
    );
    for x in ticks(x0, x1, xstep) {
        let _ = write!(
            s,
            r##"<text x="{:.1}" y="{}" text-anchor="middle">{}</text><path d="M{:.1} {} v5" stroke="black"/>"##,
            px(x),
            h - b + 18.0,
            fmt_num(x, xstep),
            px(x),
            h - b
        );
    }
    for y in ticks(y0, y1, ystep) {
        let _ = write!(
            s,
            r##"<text x="{}" y="{:.1}" text-anchor="end">{}</text><path d="M{l} {:.1} H{}" stroke="#ddd"/>"##,
            l - 6.0,
            py(y) + 4.0,
            fmt_num(y, ystep),
            py(y),
            w - r
        );
    }
    let _ = write!(
        s,
        r##"<text x="{}" y="{}" text-anchor="middle">{}</text><text x="16" y="{}" text-anchor="middle" transform="rotate(-90 16 {})">{}</text>"##,
        (l + w - r) / 2.0,
        h - 12.0,
        esc(x_label),
        (t + h - b) / 2.0,
        (t + h - b) / 2.0,
        esc(y_label)
    );
    for (k, ser) in series.iter().enumerate() {
        // beyond the palette, lines are told apart by their dashes
        let (c, d) = ser.style.unwrap_or((k, k / PALETTE.len()));
        let colour = PALETTE[c % PALETTE.len()];
        let dash = DASHES[d % DASHES.len()];
        let mut d = String::new();
        let mut pen = false;
        for &(x, y) in &ser.points {
            if !y.is_finite() {
                pen = false;
                continue;
            }
            let _ = write!(
                d,
                "{}{:.1} {:.1} ",
                if pen { "L" } else { "M" },
                px(x),
                py(y)
            );
            pen = true;
        }
        let _ = write!(
            s,
            r##"<path d="{}" stroke="{colour}" stroke-width="2" stroke-dasharray="{dash}" fill="none"/>"##,
            d.trim()
        );
        for &(x, y) in ser.points.iter().filter(|p| p.1.is_finite()) {
            let _ = write!(
                s,
                r##"<circle cx="{:.1}" cy="{:.1}" r="2.5" fill="{colour}"/>"##,
                px(x),
                py(y)
            );
        }
        let ly = t + 10.0 + 18.0 * k as f64;
        let _ = write!(
            s,
            r##"<path d="M{} {ly} h20" stroke="{colour}" stroke-width="2" stroke-dasharray="{dash}"/><text x="{}" y="{}">{}</text>"##,
            w - r + 10.0,
            w - r + 36.0,
            ly + 4.0,
            esc(&ser.name)
        );
    }
    s.push_str("</svg>\n");
    s
}

/// A round step for about five ticks over `span`: 1, 2 or 5 × 10^k.
fn nice_step(span: f64) -> f64 {
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    mag * if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    }
}

/// The multiples of `step` from `a` to `b`.
fn ticks(a: f64, b: f64, step: f64) -> Vec<f64> {
    let first = (a / step - 1e-9).ceil() as i64;
    let last = (b / step + 1e-9).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// A tick label with as many decimals as the step needs (no exponents below 10^7).
fn fmt_num(v: f64, step: f64) -> String {
    if v.abs() >= 1e7 {
        return format!("{v:.1e}");
    }
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    format!("{v:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_fall_on_round_numbers_with_the_decimals_they_need() {
        assert_eq!(nice_step(87.3), 20.0);
        assert_eq!(nice_step(0.9), 0.2);
        assert_eq!(nice_step(41_000.0), 10_000.0);
        assert_eq!(ticks(0.0, 90.0, 20.0), [0.0, 20.0, 40.0, 60.0, 80.0]);
        assert_eq!(fmt_num(0.4, 0.2), "0.4");
        assert_eq!(fmt_num(0.25, 0.05), "0.25");
        assert_eq!(fmt_num(30_000.0, 10_000.0), "30000");
        let svg = svg(
            "t",
            "x",
            "y",
            &(0..10)
                .map(|k| Series {
                    name: format!("s{k}"),
                    points: vec![(0.0, f64::from(k)), (90.0, 1234.5)],
                    style: None,
                })
                .collect::<Vec<_>>(),
        );
        // no exponents on the axes; series past the palette are dashed
        assert!(!svg.contains("e3<") && svg.contains(">1500<"), "{svg}");
        assert!(svg.contains("stroke-dasharray=\"6 3\""));
        // fixed axes: |latitude| to 90° and a fraction to 1, whatever the data
        let frac = svg_on(
            "t",
            "|latitude| (°)",
            "fraction",
            &[Series {
                name: "a".into(),
                points: vec![(2.5, 1.0), (87.5, 0.97)],
                style: None,
            }],
            Axes::LATITUDE_FRACTION,
        );
        assert!(frac.contains(">90<") && !frac.contains(">100<"), "{frac}");
        assert!(
            frac.contains(">1.0<") && !frac.contains(">1.2<") && !frac.contains(">1.5<"),
            "{frac}"
        );
    }
}
