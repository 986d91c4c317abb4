//! Exact-area coverage of polygons over a grid of texels, and the coverage of a stroke across a
//! texel.
//!
//! The polygon rasterizer adds, for each edge, the signed area it encloses to its right within
//! each row (x right, y down, texel units), split among the columns it crosses: a row's running
//! sum is then, in each texel, the polygon's signed coverage (its winding number integrated over
//! the texel). Edges left of the grid count as if on its left side, edges right of it count for
//! nothing, so a grid needs only the edges of the rows it holds.

/// Signed coverage being accumulated over `w × h` texels.
#[derive(Debug, Clone)]
pub struct Accumulator {
    w: usize,
    h: usize,
    /// Per row, `w + 2` deltas whose running sum is the coverage.
    acc: Vec<f64>,
    /// The first and last row touched.
    rows: Option<(usize, usize)>,
}

/// ∫₀ᵘ clamp(v, 0, 1) dv.
fn ramp_integral(u: f64) -> f64 {
    if u <= 0.0 {
        0.0
    } else if u <= 1.0 {
        0.5 * u * u
    } else {
        u - 0.5
    }
}

impl Accumulator {
    /// Nothing covered yet.
    pub fn new(w: usize, h: usize) -> Self {
        Self {
            w,
            h,
            acc: vec![0.0; h * (w + 2)],
            rows: None,
        }
    }

    /// Width and height, texels.
    pub fn size(&self) -> (usize, usize) {
        (self.w, self.h)
    }

    /// Forgets everything added.
    pub fn clear(&mut self) {
        if let Some((a, b)) = self.rows.take() {
            self.acc[a * (self.w + 2)..(b + 1) * (self.w + 2)].fill(0.0);
        }
    }

    /// Adds the edge from `p` to `q` (texel coordinates: x right, y down).
    pub fn edge(&mut self, p: [f64; 2], q: [f64; 2]) {
        if p[1] == q[1]
            || !(p[0].is_finite() && p[1].is_finite() && q[0].is_finite() && q[1].is_finite())
        {
            return;
        }
        let (dir, a, b) = if p[1] < q[1] {
            (1.0, p, q)
        } else {
            (-1.0, q, p)
        };
        let (lo, hi) = (a[1].max(0.0), b[1].min(self.h as f64));
        if lo >= hi {
            return;
        }
        let slope = (b[0] - a[0]) / (b[1] - a[1]);
        let x_at = |y: f64| a[0] + (y - a[1]) * slope;
        let (r0, r1) = (lo.floor() as usize, (hi.ceil() as usize).min(self.h));
        self.rows = Some(match self.rows {
            None => (r0, r1 - 1),
            Some((s, e)) => (s.min(r0), e.max(r1 - 1)),
        });
        for r in r0..r1 {
            let top = lo.max(r as f64);
            let bottom = hi.min(r as f64 + 1.0);
            let dy = bottom - top;
            if dy <= 0.0 {
                continue;
            }
            self.span(r, x_at(top), x_at(bottom), dir * dy);
        }
    }

    /// Adds, in row `r`, a piece of edge whose x runs evenly from `xa` to `xb` while it covers
    /// `d` (signed) of the row's height.
    fn span(&mut self, r: usize, xa: f64, xb: f64, d: f64) {
        let w = self.w as f64;
        let (lo, hi) = if xa <= xb { (xa, xb) } else { (xb, xa) };
        let row = &mut self.acc[r * (self.w + 2)..(r + 1) * (self.w + 2)];
        if hi <= 0.0 {
            row[0] += d;
            return;
        }
        if lo >= w {
            return;
        }
        let len = hi - lo;
        // the share of the piece left of the grid counts on its left side; right of it, nothing
        let (mut lo2, mut hi2, mut d2) = (lo, hi, d);
        if lo < 0.0 {
            let left = -lo / len;
            row[0] += d * left;
            lo2 = 0.0;
            d2 -= d * left;
        }
        if hi > w {
            d2 -= d * (hi - w) / len;
            hi2 = w;
        }
        // in column c the piece covers, on average over its height, g(c) = mean of
        // clamp(c + 1 − x, 0, 1) for x evenly in [lo2, hi2]; the deltas of g go into the row
        let span = hi2 - lo2;
        let g = |c: f64| {
            if span < 1e-12 {
                (c + 1.0 - lo2).clamp(0.0, 1.0)
            } else {
                (ramp_integral(c + 1.0 - lo2) - ramp_integral(c + 1.0 - hi2)) / span
            }
        };
        let c0 = lo2.floor() as usize;
        let c1 = (hi2.ceil() as usize).min(self.w);
        let mut prev = 0.0;
        for (c, cell) in row.iter_mut().enumerate().take(c1 + 1).skip(c0) {
            let v = g(c as f64);
            *cell += d2 * (v - prev);
            prev = v;
        }
    }

    /// The coverage, 0 … 1 per texel (row-major), the magnitude of the signed coverage clamped
    /// at 1 (rings of either orientation, overlapping parts counted once), into the rows of
    /// `out` that edges touched ([`Self::rows`]; the others are left as they are).
    pub fn coverage_into(&self, out: &mut [f32]) {
        let Some((a, b)) = self.rows else { return };
        for r in a..=b {
            let row = &self.acc[r * (self.w + 2)..(r + 1) * (self.w + 2)];
            let mut s = 0.0;
            for c in 0..self.w {
                s += row[c];
                // rounding of the running sum: within 10⁻⁹ of empty or full is
                let v = s.abs();
                out[r * self.w + c] = if v < 1e-9 {
                    0.0
                } else if v > 1.0 - 1e-9 {
                    1.0
                } else {
                    v as f32
                };
            }
        }
    }

    /// The coverage, row-major.
    pub fn coverage(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.w * self.h];
        self.coverage_into(&mut out);
        out
    }

    /// The rows touched, first and last.
    pub fn rows(&self) -> Option<(usize, usize)> {
        self.rows
    }
}

/// The share of a texel `t` wide covered by a band `half` either side of a line whose centre
/// lies `d` from the texel's centre (a box filter across the line).
pub fn band(d: f64, half: f64, t: f64) -> f64 {
    let lo = (d - t / 2.0).max(-half);
    let hi = (d + t / 2.0).min(half);
    ((hi - lo) / t).clamp(0.0, 1.0)
}

/// Distance from the origin to the segment `a`–`b` (a plane), and where along it (0 … 1) the
/// nearest point is.
pub fn to_segment(a: [f64; 2], b: [f64; 2]) -> (f64, f64) {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (-(a[0] * dx + a[1] * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (x, y) = (a[0] + t * dx, a[1] + t * dy);
    ((x * x + y * y).sqrt(), t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(acc: &mut Accumulator, x0: f64, y0: f64, x1: f64, y1: f64) {
        let p = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
        for i in 0..4 {
            acc.edge(p[i], p[(i + 1) % 4]);
        }
    }

    #[test]
    fn the_coverage_is_each_texels_share_of_the_shape() {
        // a square over fractions of texels
        let mut a = Accumulator::new(6, 5);
        square(&mut a, 0.25, 0.5, 3.75, 2.0);
        let c = a.coverage();
        let want = |x: usize, y: usize| {
            let ox = (x as f64 + 1.0).min(3.75) - (x as f64).max(0.25);
            let oy = (y as f64 + 1.0).min(2.0) - (y as f64).max(0.5);
            ox.max(0.0) * oy.max(0.0)
        };
        for y in 0..5 {
            for x in 0..6 {
                assert!(
                    (f64::from(c[y * 6 + x]) - want(x, y)).abs() < 1e-6,
                    "{x},{y}"
                );
            }
        }
        // a triangle: total area exact, and shapes reaching past every side clip to the grid
        let mut a = Accumulator::new(8, 8);
        let t = [[-3.0, 1.0], [7.3, 2.2], [2.1, 11.0]];
        for i in 0..3 {
            a.edge(t[i], t[(i + 1) % 3]);
        }
        let total: f64 = a.coverage().iter().map(|&v| f64::from(v)).sum();
        // the triangle's area inside [0,8]² by brute-force sampling
        let mut inside = 0usize;
        let n = 800;
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (
                    (i as f64 + 0.5) * 8.0 / n as f64,
                    (j as f64 + 0.5) * 8.0 / n as f64,
                );
                let s = |p: [f64; 2], q: [f64; 2]| {
                    (q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0])
                };
                let (a1, a2, a3) = (s(t[0], t[1]), s(t[1], t[2]), s(t[2], t[0]));
                if (a1 >= 0.0 && a2 >= 0.0 && a3 >= 0.0) || (a1 <= 0.0 && a2 <= 0.0 && a3 <= 0.0) {
                    inside += 1;
                }
            }
        }
        let want = inside as f64 * 64.0 / (n * n) as f64;
        assert!((total - want).abs() < 0.05, "{total} {want}");
        a.clear();
        assert!(a.coverage().iter().all(|&v| v == 0.0));
    }

    #[test]
    fn a_band_covers_its_width() {
        assert!((band(0.0, 1.0, 1.0) - 1.0).abs() < 1e-12);
        assert!((band(0.0, 0.25, 1.0) - 0.5).abs() < 1e-12);
        assert!((band(1.0, 1.0, 1.0) - 0.5).abs() < 1e-12);
        assert_eq!(band(2.0, 1.0, 1.0), 0.0);
        // summed over texels across it, a band covers its width
        let s: f64 = (-10..=10).map(|i| band(f64::from(i) + 0.3, 1.1, 1.0)).sum();
        assert!((s - 2.2).abs() < 1e-12);
    }
}
