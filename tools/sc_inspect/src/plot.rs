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
}

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
    y1 += (y1 - y0) * 0.05;
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
    for k in 0..=5 {
        let x = x0 + (x1 - x0) * f64::from(k) / 5.0;
        let y = y0 + (y1 - y0) * f64::from(k) / 5.0;
        let _ = write!(
            s,
            r##"<text x="{:.1}" y="{}" text-anchor="middle">{}</text><text x="{}" y="{:.1}" text-anchor="end">{}</text><path d="M{l} {:.1} H{}" stroke="#ddd"/>"##,
            px(x),
            h - b + 16.0,
            fmt_num(x),
            l - 6.0,
            py(y) + 4.0,
            fmt_num(y),
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
        let colour = PALETTE[k % PALETTE.len()];
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
            r##"<path d="{}" stroke="{colour}" stroke-width="2" fill="none"/>"##,
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
            r##"<path d="M{} {ly} h20" stroke="{colour}" stroke-width="2"/><text x="{}" y="{}">{}</text>"##,
            w - r + 10.0,
            w - r + 36.0,
            ly + 4.0,
            esc(&ser.name)
        );
    }
    s.push_str("</svg>\n");
    s
}

fn fmt_num(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1000.0 || v.abs() < 0.01 {
        format!("{v:.2e}")
    } else if v.abs() >= 10.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}
