//! What the keys and the mouse do: the one table of keys and mouse actions (the help overlay,
//! `view --help` and the README show it) and the key → action map.

use winit::keyboard::KeyCode;

use sc_view_space::camera::Mode;

/// Every key and mouse action of the window: what to press, what it does.
pub const KEYS: &[(&str, &str)] = &[
    (
        "left drag",
        "orbit: turn the globe, the grabbed point stays under the cursor; fly, walk: look around",
    ),
    (
        "wheel",
        "zoom towards the point under the cursor (orbit, fly); walk: nothing",
    ),
    ("double-click", "fly to the point under the cursor"),
    ("W A S D, arrows", "move forward, left, back, right"),
    ("Q, E", "down, up"),
    ("Shift", "move five times faster"),
    ("1, 2, 3", "orbit, fly, walk"),
    ("N", "turn north up"),
    ("Home, R", "back to the start"),
    ("/, Ctrl+F", "find a place, or a latitude and longitude"),
    (
        "M",
        "measure: click two points (great-circle and ground distance, height profile)",
    ),
    ("T", "play or stop the time of day"),
    (
        "F12",
        "screenshot: a PNG named with the camera, in the working folder",
    ),
    ("F1, ?", "this help"),
    ("Tab", "hide or show the panel"),
    ("F", "wireframe"),
    ("L", "level colours"),
    (
        "Esc",
        "close the help, the search or the measure; else quit",
    ),
];

/// What a key asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Orbit, fly or walk.
    Mode(Mode),
    /// Heading 0.
    NorthUp,
    /// Back to the starting camera.
    Reset,
    /// Focus the place search.
    Search,
    /// Show or hide the help overlay.
    Help,
    /// Show or hide the panel.
    Panel,
    /// Start or end measuring.
    Measure,
    /// Play or stop the time of day.
    PlayTime,
    /// Save the window as a PNG named with the camera.
    Screenshot,
    /// Wireframe on or off.
    Wireframe,
    /// Level colours on or off.
    LevelColors,
    /// Close what is open, or quit.
    Escape,
}

/// The action of a key pressed (`ctrl`, `shift`: modifiers held), if it has one. Movement keys
/// (W/A/S/D, arrows, Q/E, Shift) act while held and are read from the keys down instead.
pub fn action_for(key: KeyCode, ctrl: bool, shift: bool) -> Option<Action> {
    Some(match key {
        KeyCode::Digit1 => Action::Mode(Mode::Orbit),
        KeyCode::Digit2 => Action::Mode(Mode::Fly),
        KeyCode::Digit3 => Action::Mode(Mode::Walk),
        KeyCode::KeyN => Action::NorthUp,
        KeyCode::Home | KeyCode::KeyR => Action::Reset,
        KeyCode::KeyF if ctrl => Action::Search,
        KeyCode::Slash if shift => Action::Help,
        KeyCode::Slash => Action::Search,
        KeyCode::F1 => Action::Help,
        KeyCode::Tab => Action::Panel,
        KeyCode::KeyM => Action::Measure,
        KeyCode::KeyT => Action::PlayTime,
        KeyCode::F12 => Action::Screenshot,
        KeyCode::KeyF => Action::Wireframe,
        KeyCode::KeyL => Action::LevelColors,
        KeyCode::Escape => Action::Escape,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sc_view_plan::frame::FrameTimer;
    use sc_view_space::camera::{Camera, Controller, Input};
    use std::time::{Duration, Instant};

    const R: f64 = 6_371_000.0;

    /// Holds W for `seconds` at `fps` frames a second through the frame timer; the camera's
    /// latitude change (flying north).
    fn fly(fps: f64, seconds: f64) -> (f64, FrameTimer) {
        let start = Camera {
            lat_deg: 10.0,
            lon_deg: 20.0,
            alt: 1000.0,
            heading: 0.0,
            pitch: -10.0,
            fov: 60.0,
        };
        let mut c = Controller::new(start, R);
        let mut timer = FrameTimer::default();
        let t0 = Instant::now();
        let frames = (seconds * fps).round() as u32;
        for k in 0..=frames {
            let dt = timer.tick(t0 + Duration::from_secs_f64(f64::from(k) / fps));
            c.update(&Input {
                dt,
                forward: 1.0,
                ..Input::default()
            });
        }
        (c.camera.lat_deg - start.lat_deg, timer)
    }

    #[test]
    fn the_camera_moves_in_real_time_and_the_frame_rate_is_what_it_is() {
        let (slow, slow_timer) = fly(0.5, 4.0);
        let (fast, fast_timer) = fly(30.0, 4.0);
        assert!(slow > 0.0);
        assert!(
            (slow - fast).abs() < 1e-9 * fast.abs(),
            "0.5 fps moved {slow}°, 30 fps {fast}°"
        );
        assert!(
            (slow_timer.fps() - 0.5).abs() < 1e-6,
            "{}",
            slow_timer.fps()
        );
        assert!(
            (fast_timer.fps() - 30.0).abs() < 1e-3,
            "{}",
            fast_timer.fps()
        );
        assert_eq!(slow_timer.history.len(), 2);
        assert!((slow_timer.history[0] - 2000.0).abs() < 1e-6);
        assert_eq!(fast_timer.history.len(), 120);
    }

    #[test]
    fn keys_do_what_the_help_says() {
        let mut c = Controller::new(
            Camera {
                lat_deg: 46.0,
                lon_deg: 7.7,
                alt: 3000.0,
                heading: 137.0,
                pitch: -20.0,
                fov: 60.0,
            },
            R,
        );
        assert_eq!(
            action_for(KeyCode::KeyN, false, false),
            Some(Action::NorthUp)
        );
        c.north_up();
        assert_eq!(c.camera.heading, 0.0);
        assert_eq!(action_for(KeyCode::Slash, false, true), Some(Action::Help));
        assert_eq!(
            action_for(KeyCode::Slash, false, false),
            Some(Action::Search)
        );
        assert_eq!(action_for(KeyCode::KeyF, true, false), Some(Action::Search));
        assert_eq!(
            action_for(KeyCode::KeyF, false, false),
            Some(Action::Wireframe)
        );
        assert_eq!(action_for(KeyCode::Home, false, false), Some(Action::Reset));
        assert_eq!(action_for(KeyCode::F1, false, false), Some(Action::Help));
        // every key with an action is in the help's table
        let listed = KEYS.iter().map(|(k, _)| *k).collect::<Vec<_>>().join(" | ");
        for key in [
            "N", "Home", "R", "F1", "?", "Tab", "F12", "/", "Ctrl+F", "M", "T",
        ] {
            assert!(
                listed
                    .split([',', '|', ' '])
                    .any(|w| w.trim() == key || w.trim() == format!("{key},")),
                "{key} missing from {listed}"
            );
        }
    }

    #[test]
    fn the_readme_shows_this_table_of_keys() {
        let readme = include_str!("../../../README.md");
        let rows: Vec<&str> = readme
            .lines()
            .skip_while(|l| *l != "| keys and mouse | what they do |")
            .skip(2)
            .take_while(|l| l.starts_with('|'))
            .collect();
        let want: Vec<String> = KEYS.iter().map(|(k, w)| format!("| {k} | {w} |")).collect();
        assert_eq!(rows, want, "README's keys table is not controls::KEYS");
    }
}
