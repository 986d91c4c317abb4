//! Level ids: isotropic levels ℓ and the anisotropic levels (ℓ, a) that are 2^a coarser in longitude.
//!
//! Why anisotropic levels exist: one longitude texel of an isotropic level covers `cos(lat)` times the
//! ground distance of one latitude texel, so towards the poles longitude is oversampled by `1/cos(lat)`.
//! A clipmap ring of angular radius θ̃ around a viewer at latitude `lat` spans ≈ `2θ̃/cos(lat)` of
//! longitude (spherical clipmaps §4.1), so the viewer wants textures that are coarser in longitude by
//! the same factor, in power-of-two steps. Level (ℓ, a) keeps the rows of ℓ and has 2^a times fewer
//! columns; after the pyramid has band-limited longitude to what the sphere supports (§4.3) it loses
//! nothing where `2^a·cos(lat) ≤ 1`, i.e. for `|lat| ≥ acos(2^−a)`: 60° for a = 1, 75.5° for a = 2,
//! 82.8° for a = 3, 86.4° for a = 4 … Only tile rows reaching into that band are stored
//! ([`crate::GridSpec::level_has_tile_row`]); the rest of an anisotropic array stays empty.

use std::fmt;
use std::str::FromStr;

use crate::GridError;

/// The finest level a store can hold: with T = 256 that is 2^27 columns, ~0.3 m at the equator.
pub const LEVEL_MAX: u32 = 20;
/// The largest anisotropy: a = 8 serves |lat| ≥ 89.78°, beyond that a pole tile row covers the rest.
pub const ANISO_MAX: u32 = 8;

/// One level of the pyramid: isotropic level `level`, `aniso` times halved in longitude.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct LevelId {
    /// Isotropic level ℓ: `H = T·2^ℓ` rows.
    pub level: u32,
    /// Anisotropy a: `W = 2·T·2^(ℓ−a)` columns; 0 for an isotropic level.
    pub aniso: u32,
}

impl LevelId {
    /// An isotropic level, checked against [`LEVEL_MAX`].
    pub fn iso(level: u32) -> Result<Self, GridError> {
        Self::new(level, 0)
    }

    /// Level (ℓ, a), checked: `ℓ ≤ LEVEL_MAX`, `a ≤ min(ℓ, ANISO_MAX)`.
    pub fn new(level: u32, aniso: u32) -> Result<Self, GridError> {
        if level > LEVEL_MAX || aniso > level.min(ANISO_MAX) {
            return Err(GridError::Level { level, aniso });
        }
        Ok(Self { level, aniso })
    }

    /// Whether this is an isotropic level (a = 0).
    pub fn is_iso(self) -> bool {
        self.aniso == 0
    }

    /// The name used for the level's array in a store: `L04` or `L04A2`.
    pub fn key(self) -> String {
        if self.aniso == 0 {
            format!("L{:02}", self.level)
        } else {
            format!("L{:02}A{}", self.level, self.aniso)
        }
    }

    /// Parses [`LevelId::key`] back; `None` for anything else.
    pub fn from_key(key: &str) -> Option<Self> {
        let rest = key.strip_prefix('L')?;
        let (l, a) = match rest.split_once('A') {
            Some((l, a)) => (l, a.parse().ok()?),
            None => (rest, 0),
        };
        if l.len() != 2 {
            return None;
        }
        let id = Self::new(l.parse().ok()?, a).ok()?;
        (id.key() == key).then_some(id)
    }

    /// All anisotropic levels that exist for isotropic level `level`, a = 1..=min(ℓ, ANISO_MAX).
    pub fn aniso_levels_of(level: u32) -> impl Iterator<Item = LevelId> {
        (1..=level.min(ANISO_MAX)).map(move |aniso| LevelId { level, aniso })
    }
}

impl fmt::Display for LevelId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.aniso == 0 {
            write!(f, "{}", self.level)
        } else {
            write!(f, "{},{}", self.level, self.aniso)
        }
    }
}

impl FromStr for LevelId {
    type Err = String;

    /// Parses `ℓ` or `ℓ,a` (as the CLI takes it).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || format!("expected a level as `L` or `L,A` (e.g. 4 or 4,2), found `{s}`");
        let (l, a) = match s.split_once(',') {
            Some((l, a)) => (l.trim(), a.trim()),
            None => (s.trim(), "0"),
        };
        let level = l.parse().map_err(|_| bad())?;
        let aniso = a.parse().map_err(|_| bad())?;
        LevelId::new(level, aniso).map_err(|e| e.to_string())
    }
}

/// The latitude (degrees) poleward of which anisotropy `a` loses nothing: `acos(2^−a)`.
pub fn aniso_min_abs_lat_deg(aniso: u32) -> f64 {
    (0.5f64).powi(aniso as i32).acos().to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_round_trip() {
        for level in 0..=LEVEL_MAX {
            for aniso in 0..=level.min(ANISO_MAX) {
                let id = LevelId::new(level, aniso).expect("valid");
                assert_eq!(LevelId::from_key(&id.key()), Some(id));
                assert_eq!(id.to_string().parse::<LevelId>(), Ok(id));
            }
        }
        assert_eq!(LevelId::from_key("L4"), None);
        assert_eq!(LevelId::from_key("L04A0"), None);
        assert_eq!(LevelId::from_key("L02A3"), None, "a > ℓ does not exist");
        assert!("3,4".parse::<LevelId>().is_err());
        assert!("x".parse::<LevelId>().is_err());
    }

    #[test]
    fn aniso_bands() {
        assert_eq!(aniso_min_abs_lat_deg(0), 0.0);
        assert!((aniso_min_abs_lat_deg(1) - 60.0).abs() < 1e-12);
        assert!((aniso_min_abs_lat_deg(2) - 75.522_487_814_070_06).abs() < 1e-9);
        for a in 1..=ANISO_MAX {
            assert!(aniso_min_abs_lat_deg(a) > aniso_min_abs_lat_deg(a - 1));
        }
    }
}
