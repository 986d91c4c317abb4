//! Tile sources shared by the viewer crates' tests (`viewer/gpu/tests` includes this file too).

use sc_view_data::stream::{Tile, TileData, TileError, TileKey, TileSource};

/// The tiles of `inner`, failing for grids finer than the level given (a store damaged below
/// some level).
#[derive(Debug)]
pub struct FailsBelow<S>(pub u32, pub S);

impl<S: TileSource> TileSource for FailsBelow<S> {
    fn make(&self, key: &TileKey, n: u32, inputs: &[Tile]) -> Result<TileData, TileError> {
        if key.grid.level > self.0 {
            return Err(TileError::Store("checksum mismatch".into()));
        }
        self.1.make(key, n, inputs)
    }
}
