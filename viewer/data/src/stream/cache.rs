//! The tile cache: tiles by key, pruned to a budget by distance to the focus.

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex, MutexGuard};

use super::{GridId, Tile, TileData, TileKey};

/// Where a grid's clipmap window is: the quad's first tile (x, y).
pub type Focus = HashMap<(u32, GridId), (i64, i64)>;

#[derive(Debug, Default)]
struct CacheInner {
    tiles: HashMap<TileKey, Tile>,
    failed: HashSet<TileKey>,
    bytes: usize,
}

/// Tiles by locator (see the module documentation).
#[derive(Debug)]
pub struct TileCache {
    inner: Mutex<CacheInner>,
    budget: usize,
}

impl TileCache {
    /// An empty cache that prunes down to `budget` bytes.
    pub fn new(budget: usize) -> Self {
        Self {
            inner: Mutex::new(CacheInner::default()),
            budget,
        }
    }

    fn lock(&self) -> MutexGuard<'_, CacheInner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The tile, if made.
    pub fn get(&self, key: &TileKey) -> Option<Tile> {
        self.lock().tiles.get(key).cloned()
    }

    /// Whether the tile is made.
    pub fn contains(&self, key: &TileKey) -> bool {
        self.lock().tiles.contains_key(key)
    }

    /// Stores a made tile.
    pub fn insert(&self, key: TileKey, tile: TileData) {
        let mut c = self.lock();
        let bytes = tile.bytes();
        if let Some(old) = c.tiles.insert(key, Arc::new(tile)) {
            c.bytes -= old.bytes();
        }
        c.bytes += bytes;
    }

    /// Records that the tile cannot be made; true the first time (log it once).
    pub fn fail(&self, key: TileKey) -> bool {
        self.lock().failed.insert(key)
    }

    /// Whether making the tile failed.
    pub fn is_failed(&self, key: &TileKey) -> bool {
        self.lock().failed.contains(key)
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.lock().bytes
    }

    /// Tiles held.
    pub fn len(&self) -> usize {
        self.lock().tiles.len()
    }

    /// Tiles held of one source.
    pub fn tiles_of(&self, source: u32) -> usize {
        self.lock()
            .tiles
            .keys()
            .filter(|k| k.source == source)
            .count()
    }

    /// Whether no tile is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Drops the tile of `key`, if held.
    pub fn remove(&self, key: &TileKey) {
        let mut c = self.lock();
        if let Some(old) = c.tiles.remove(key) {
            c.bytes -= old.bytes();
        }
    }

    /// Drops every tile, and forgets every failure.
    pub fn clear(&self) {
        let mut c = self.lock();
        c.tiles.clear();
        c.failed.clear();
        c.bytes = 0;
    }

    /// Drops every tile of the given sources (their parameters changed).
    pub fn invalidate(&self, sources: &[u32]) {
        let mut c = self.lock();
        let CacheInner {
            tiles,
            failed,
            bytes,
        } = &mut *c;
        tiles.retain(|k, t| {
            let keep = !sources.contains(&k.source);
            if !keep {
                *bytes -= t.bytes();
            }
            keep
        });
        failed.retain(|k| !sources.contains(&k.source));
    }

    /// Prunes to the budget: tiles farthest from their grid's focus go first (tiles of grids
    /// out of focus before all others); the quad and the ring adjacent to it are always kept,
    /// and so are the tiles in `keep` (those asked for, prefetches included).
    pub fn prune(&self, focus: &Focus) {
        self.prune_keeping(focus, &HashSet::new());
    }

    /// [`Self::prune`], never dropping the tiles in `keep`.
    pub fn prune_keeping(&self, focus: &Focus, keep: &HashSet<TileKey>) {
        let mut c = self.lock();
        if c.bytes <= self.budget {
            return;
        }
        let mut far: Vec<(i64, TileKey)> = c
            .tiles
            .keys()
            .filter_map(|k| {
                let d = match focus.get(&(k.source, k.grid)) {
                    None => i64::MAX,
                    Some(&(x0, y0)) => {
                        let around = k.grid.tiles_around();
                        // circular distance in x from the quad's columns x0, x0 + 1
                        let dx = [x0, x0 + 1]
                            .iter()
                            .map(|&q| {
                                let d = (k.x - q).rem_euclid(around);
                                d.min(around - d)
                            })
                            .min()
                            .unwrap_or(0);
                        let dy = if k.y < y0 {
                            y0 - k.y
                        } else {
                            (k.y - (y0 + 1)).max(0)
                        };
                        dx.max(dy)
                    }
                };
                (d > 1 && !keep.contains(k)).then_some((d, *k))
            })
            .collect();
        far.sort_unstable_by(|a, b| b.cmp(a));
        for (_, k) in far {
            if c.bytes <= self.budget {
                break;
            }
            if let Some(t) = c.tiles.remove(&k) {
                c.bytes -= t.bytes();
            }
        }
    }
}
