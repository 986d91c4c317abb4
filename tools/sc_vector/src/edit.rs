//! Planning edits to heights: polygons that set, raise or cap the ground, with an edge feathered
//! over a distance on the ground.

use std::sync::Arc;

use serde::Deserialize;

use crate::layer::{VectorLayer, Window};

/// What an edit does to the heights inside its polygons.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EditRule {
    /// The ground at this height, metres (a reservoir's surface, a levelled site).
    Set(f64),
    /// The ground raised (or, negative, lowered) by this much, metres.
    Add(f64),
    /// The ground no higher than this, metres (a cut).
    ClampMax(f64),
}

impl EditRule {
    fn apply(self, h: f32) -> f32 {
        match self {
            EditRule::Set(v) => v as f32,
            EditRule::Add(v) => h + v as f32,
            EditRule::ClampMax(v) => h.min(v as f32),
        }
    }
}

/// A height edit: a layer's polygons, a rule, and a feather (metres inside the edge over which
/// the edit fades in; 0: the polygon's coverage of each texel).
#[derive(Debug)]
pub struct HeightEdit {
    /// The polygons.
    pub layer: Arc<VectorLayer>,
    /// What they do.
    pub rule: EditRule,
    /// Metres.
    pub feather: f64,
}

impl HeightEdit {
    /// Checks the settings.
    pub fn new(layer: Arc<VectorLayer>, rule: EditRule, feather: f64) -> Result<Self, String> {
        let v = match rule {
            EditRule::Set(v) | EditRule::Add(v) | EditRule::ClampMax(v) => v,
        };
        if !(v.is_finite() && v.abs() <= 1e5) {
            return Err(format!("the edit's height {v} must be within ±100 km"));
        }
        if !(feather.is_finite() && (0.0..=1e6).contains(&feather)) {
            return Err(format!("feather {feather} must be 0 … 1000 km"));
        }
        Ok(Self {
            layer,
            rule,
            feather,
        })
    }

    /// How much of the edit each texel of `win` gets, 0 … 1: the coverage, or with a feather,
    /// a smooth step from 0 at the edge to 1 at `feather` metres inside.
    pub fn weights(&self, win: &Window) -> Vec<f32> {
        if self.feather <= 0.0 {
            return self.layer.coverage(win);
        }
        let (dist, cover) = self.layer.edge_distance(win, self.feather);
        dist.iter()
            .zip(&cover)
            .map(|(&d, &c)| {
                if c < 0.5 {
                    0.0
                } else {
                    let t = (f64::from(d) / self.feather).clamp(0.0, 1.0);
                    (t * t * (3.0 - 2.0 * t)) as f32
                }
            })
            .collect()
    }

    /// Edits `heights` (row-major over `win`; NaN, no data, stays NaN) with `strength` (0 … 1)
    /// of the edit.
    pub fn apply(&self, win: &Window, heights: &mut [f32], strength: f32) {
        for (h, w) in heights.iter_mut().zip(self.weights(win)) {
            let w = w * strength;
            if w > 0.0 && !h.is_nan() {
                *h += (self.rule.apply(*h) - *h) * w;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Edges, Feature, Geometry, Style};
    use std::collections::BTreeMap;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn a_set_edit_reads_its_height_inside_its_feather_and_fades_out() {
        let sq = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]];
        let f = Feature {
            geometry: Geometry::Polygons(vec![vec![sq]]),
            properties: BTreeMap::new(),
        };
        let radius = 6_371_000.0;
        let layer = Arc::new(
            VectorLayer::new(vec![f], Style::default(), Edges::Lonlat, radius).expect("l"),
        );
        let e = HeightEdit::new(layer, EditRule::Set(1950.0), 10_000.0).expect("edit");
        let d = 0.01f64.to_radians();
        let win = Window {
            lon0: -0.2f64.to_radians(),
            colat0: FRAC_PI_2 - 1.2f64.to_radians(),
            dlon: d,
            dcolat: d,
            w: 140,
            h: 140,
        };
        let mut h = vec![500.0f32; 140 * 140];
        e.apply(&win, &mut h, 1.0);
        // the middle (55 km inside) is 1950, outside is 500, the edge in between
        assert_eq!(h[70 * 140 + 70], 1950.0);
        assert_eq!(h[5 * 140 + 5], 500.0);
        let edge = h[70 * 140 + 21];
        assert!(edge > 500.0 && edge < 1950.0, "{edge}");
        assert!(
            HeightEdit::new(
                Arc::new(
                    VectorLayer::new(vec![], Style::default(), Edges::Lonlat, radius).expect("l")
                ),
                EditRule::Add(f64::NAN),
                0.0
            )
            .is_err()
        );
    }
}
