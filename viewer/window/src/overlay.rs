//! What the window draws over the planet: a scale bar true at the cursor's ground (or the
//! picture's centre), a compass with the heading and tilt, and the help overlay of every key and
//! mouse action ([`crate::controls::KEYS`]).

use crate::controls::KEYS;
use crate::panel::{PanelFacts, distance_text};

/// A round length (1, 2 or 5 × 10ⁿ metres) of about `target` metres or less.
pub(crate) fn round_length(target: f64) -> f64 {
    if target.is_nan() || target <= 0.0 {
        return 0.0;
    }
    let p = 10f64.powf(target.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|k| k * p)
        .find(|&l| l <= target)
        .unwrap_or(p)
}

/// Metres a pixel spans at `distance` metres from the eye, straight on, in a picture `rows`
/// pixels high with vertical field of view `fov_deg`.
pub(crate) fn metres_per_pixel(distance: f64, fov_deg: f64, rows: u32) -> f64 {
    distance * 2.0 * (fov_deg.to_radians() / 2.0).tan() / f64::from(rows.max(1))
}

/// The scale bar (bottom left) and the compass (top right).
pub(crate) fn instruments(ctx: &egui::Context, f: &PanelFacts) {
    let screen = ctx.content_rect();
    let painter = ctx.layer_painter(egui::LayerId::new(
        egui::Order::Foreground,
        egui::Id::new("instruments"),
    ));
    let ppp = ctx.pixels_per_point();
    let ink = egui::Color32::WHITE;
    let shadow = egui::Color32::from_black_alpha(160);
    // scale bar: at the ground under the cursor (its distance), else none
    if let Some(p) = f.pointed {
        let m_per_px = metres_per_pixel(p.distance, f.camera.fov, f.size.1);
        let length = round_length(m_per_px * 150.0);
        let px = (length / m_per_px) as f32 / ppp;
        let y = screen.bottom() - 24.0;
        let x0 = screen.left() + 16.0;
        let bar = [egui::pos2(x0, y), egui::pos2(x0 + px, y)];
        painter.line_segment(bar, egui::Stroke::new(5.0, shadow));
        painter.line_segment(bar, egui::Stroke::new(3.0, ink));
        for x in [x0, x0 + px] {
            painter.line_segment(
                [egui::pos2(x, y - 6.0), egui::pos2(x, y + 3.0)],
                egui::Stroke::new(2.0, ink),
            );
        }
        painter.text(
            egui::pos2(x0, y - 8.0),
            egui::Align2::LEFT_BOTTOM,
            format!("{} at the cursor", distance_text(length)),
            egui::FontId::proportional(13.0),
            ink,
        );
    }
    // compass: the needle points north on screen; tilt from straight down
    let c = egui::pos2(screen.right() - 46.0, screen.top() + 46.0);
    let r = 30.0;
    painter.circle(c, r, shadow, egui::Stroke::new(1.5, ink));
    let a = (-f.camera.heading).to_radians() as f32;
    let (s, k) = a.sin_cos();
    let tip = c + egui::vec2(s, -k) * (r - 4.0);
    let tail = c - egui::vec2(s, -k) * (r - 10.0);
    painter.line_segment([tail, c], egui::Stroke::new(3.0, ink));
    painter.line_segment([c, tip], egui::Stroke::new(3.0, egui::Color32::RED));
    painter.text(
        tip + egui::vec2(s, -k) * 8.0,
        egui::Align2::CENTER_CENTER,
        "N",
        egui::FontId::proportional(12.0),
        ink,
    );
    painter.text(
        c + egui::vec2(0.0, r + 10.0),
        egui::Align2::CENTER_CENTER,
        format!(
            "{:.0}° · tilt {:.0}°",
            f.camera.heading.rem_euclid(360.0),
            90.0 + f.camera.pitch
        ),
        egui::FontId::proportional(12.0),
        ink,
    );
}

/// The help overlay: every key and mouse action; closes with its button, F1, ? or Esc.
pub(crate) fn help(ctx: &egui::Context, open: &mut bool) {
    egui::Window::new("keys and mouse (F1 or ? closes)")
        .open(open)
        .anchor(egui::Align2::CENTER_CENTER, egui::vec2(0.0, 0.0))
        .collapsible(false)
        .show(ctx, |ui| {
            egui::Grid::new("keys").striped(true).show(ui, |ui| {
                for (k, what) in KEYS {
                    ui.strong(*k);
                    ui.label(*what);
                    ui.end_row();
                }
            });
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_bars_are_round_and_true() {
        assert_eq!(round_length(1234.0), 1000.0);
        assert_eq!(round_length(2600.0), 2000.0);
        assert_eq!(round_length(9.9), 5.0);
        assert_eq!(round_length(0.0), 0.0);
        // 1000 px high, 90° field of view: at 500 m a pixel spans a metre
        assert!((metres_per_pixel(500.0, 90.0, 1000) - 1.0).abs() < 1e-12);
    }
}
