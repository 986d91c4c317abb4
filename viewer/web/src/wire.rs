//! The messages between the page and its tile makers (web workers), as bytes: a task (the
//! tile's key and the tiles it is made from), a made tile or why it failed, and the store reads a
//! maker opened the store with ([`crate::recorded`]). Little-endian; read back with every length
//! checked, so a message that does not parse is an error, never a panic.

use sc_view_data::stream::{GridId, TileData, TileError, TileKey};

/// Writes a message.
#[derive(Debug, Default)]
pub struct Writer(pub Vec<u8>);

impl Writer {
    pub fn u8(&mut self, v: u8) {
        self.0.push(v);
    }

    pub fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    pub fn i64(&mut self, v: i64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// A length, then the bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        self.u64(b.len() as u64);
        self.0.extend_from_slice(b);
    }

    pub fn key(&mut self, k: &TileKey) {
        self.u32(k.source);
        self.u32(k.grid.level);
        self.u32(k.grid.k);
        self.i64(k.x);
        self.i64(k.y);
    }

    fn f32s(&mut self, v: &[f32]) {
        self.u64(v.len() as u64);
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }

    pub fn tile(&mut self, t: &TileData) {
        match t {
            TileData::Height(v) => {
                self.u8(0);
                self.f32s(v);
            }
            TileData::Color(v) => {
                self.u8(1);
                self.bytes(v);
            }
            TileData::ShadedHeight { heights, shade } => {
                self.u8(2);
                self.f32s(heights);
                self.f32s(shade);
            }
        }
    }
}

/// Reads a message.
#[derive(Debug)]
pub struct Reader<'a> {
    rest: &'a [u8],
}

impl<'a> Reader<'a> {
    pub fn new(b: &'a [u8]) -> Self {
        Self { rest: b }
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.rest.len() < n {
            return Err(format!(
                "a message cut short: {n} bytes wanted, {} left",
                self.rest.len()
            ));
        }
        let (a, b) = self.rest.split_at(n);
        self.rest = b;
        Ok(a)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let mut a = [0; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }

    pub fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }

    pub fn u32(&mut self) -> Result<u32, String> {
        self.array().map(u32::from_le_bytes)
    }

    pub fn u64(&mut self) -> Result<u64, String> {
        self.array().map(u64::from_le_bytes)
    }

    pub fn i64(&mut self) -> Result<i64, String> {
        self.array().map(i64::from_le_bytes)
    }

    /// A count of items of `size` bytes each, checked against what is left.
    fn count(&mut self, size: usize) -> Result<usize, String> {
        let n = self.u64()?;
        match usize::try_from(n) {
            Ok(n) if n.checked_mul(size).is_some_and(|b| b <= self.rest.len()) => Ok(n),
            _ => Err(format!("a message names {n} items, more than it holds")),
        }
    }

    pub fn bytes(&mut self) -> Result<&'a [u8], String> {
        let n = self.count(1)?;
        self.take(n)
    }

    pub fn string(&mut self) -> Result<String, String> {
        Ok(String::from_utf8_lossy(self.bytes()?).into_owned())
    }

    pub fn key(&mut self) -> Result<TileKey, String> {
        Ok(TileKey {
            source: self.u32()?,
            grid: GridId {
                level: self.u32()?,
                k: self.u32()?,
            },
            x: self.i64()?,
            y: self.i64()?,
        })
    }

    fn f32s(&mut self) -> Result<Vec<f32>, String> {
        let n = self.count(4)?;
        let b = self.take(n * 4)?;
        Ok(b.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    }

    pub fn tile(&mut self) -> Result<TileData, String> {
        match self.u8()? {
            0 => Ok(TileData::Height(self.f32s()?)),
            1 => Ok(TileData::Color(self.bytes()?.to_vec())),
            2 => {
                let heights = self.f32s()?;
                let shade = self.f32s()?;
                if shade.len() != heights.len() {
                    return Err(format!(
                        "a tile of {} heights with {} shades",
                        heights.len(),
                        shade.len()
                    ));
                }
                Ok(TileData::ShadedHeight { heights, shade })
            }
            t => Err(format!("a tile of unknown kind {t}")),
        }
    }

    /// Whether everything was read.
    pub fn done(&self) -> Result<(), String> {
        if self.rest.is_empty() {
            Ok(())
        } else {
            Err(format!("{} bytes after the message's end", self.rest.len()))
        }
    }
}

/// A task for a maker: make `key` from these inputs (tiles the page has; any it lacks the maker
/// makes itself).
pub fn task<'t>(
    key: &TileKey,
    inputs: impl IntoIterator<Item = (TileKey, &'t TileData)>,
) -> Vec<u8> {
    let inputs: Vec<_> = inputs.into_iter().collect();
    let mut w = Writer::default();
    w.key(key);
    w.u64(inputs.len() as u64);
    for (k, t) in inputs {
        w.key(&k);
        w.tile(t);
    }
    w.0
}

/// A task's key and inputs.
pub fn read_task(b: &[u8]) -> Result<(TileKey, Vec<(TileKey, TileData)>), String> {
    let mut r = Reader::new(b);
    let key = r.key()?;
    // an input is at least a key and a kind
    let n = r.count(29)?;
    let mut inputs = Vec::with_capacity(n);
    for _ in 0..n {
        inputs.push((r.key()?, r.tile()?));
    }
    r.done()?;
    Ok((key, inputs))
}

/// A maker's answer: the tile of `key`, or why it could not be made.
pub fn made(key: &TileKey, made: &Result<TileData, TileError>) -> Vec<u8> {
    let mut w = Writer::default();
    w.key(key);
    match made {
        Ok(t) => {
            w.u8(1);
            w.tile(t);
        }
        Err(e) => {
            w.u8(0);
            w.bytes(e.to_string().as_bytes());
        }
    }
    w.0
}

/// An answer's key and tile (a failure in the maker's words).
pub fn read_made(b: &[u8]) -> Result<(TileKey, Result<TileData, TileError>), String> {
    let mut r = Reader::new(b);
    let key = r.key()?;
    let made = match r.u8()? {
        1 => Ok(r.tile()?),
        0 => Err(TileError::Other(r.string()?)),
        t => return Err(format!("an answer of unknown kind {t}")),
    };
    r.done()?;
    Ok((key, made))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(source: u32, x: i64, y: i64) -> TileKey {
        TileKey {
            source,
            grid: GridId { level: 7, k: 40 },
            x,
            y,
        }
    }

    #[test]
    fn tasks_and_answers_read_back_as_written() {
        let h = TileData::Height(vec![1.5, f32::NAN, -1e30, 0.0]);
        let c = TileData::Color(vec![1, 2, 3, 255]);
        let k = key(3, (1 << 40) - 1, -2);
        let b = task(&k, [(key(0, 5, -2), &h), (key(1, 5, -2), &c)]);
        let (k2, inputs) = read_task(&b).expect("reads");
        assert_eq!(k2, k);
        assert_eq!(inputs.len(), 2);
        assert_eq!(inputs[0].0, key(0, 5, -2));
        let TileData::Height(v) = &inputs[0].1 else {
            panic!("heights")
        };
        // bit for bit, NaN included
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(v), bits(&[1.5, f32::NAN, -1e30, 0.0]));
        assert_eq!(inputs[1], (key(1, 5, -2), c.clone()));
        assert_eq!(read_made(&made(&k, &Ok(c.clone()))), Ok((k, Ok(c))));
        let e = TileError::Store("height/3/c/0/1: no answer in 20 s".into());
        let (_, back) = read_made(&made(&k, &Err(e.clone()))).expect("reads");
        assert_eq!(back.map_err(|e| e.to_string()), Err(e.to_string()));
        assert_eq!(read_task(&task(&k, [])), Ok((k, Vec::new())));
        // heights with their detail's shade: both come back
        let s = TileData::ShadedHeight {
            heights: vec![2.0, -3.5],
            shade: vec![0.25, 0.0],
        };
        assert_eq!(read_made(&made(&k, &Ok(s.clone()))), Ok((k, Ok(s))));
    }

    #[test]
    fn damaged_messages_are_errors() {
        let h = TileData::Height(vec![1.0; 16]);
        let b = task(&key(1, 0, 0), [(key(0, 0, 0), &h)]);
        for cut in 0..b.len() {
            assert!(read_task(&b[..cut]).is_err(), "cut at {cut}");
        }
        let mut longer = b.clone();
        longer.push(0);
        assert!(read_task(&longer).is_err());
        // a count far beyond the message
        let mut huge = b.clone();
        huge[28..36].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(read_task(&huge).is_err());
        let mut kind = made(&key(0, 0, 0), &Ok(h));
        kind[28] = 9;
        assert!(read_made(&kind).is_err());
        // a shade that does not cover its heights
        let s = TileData::ShadedHeight {
            heights: vec![1.0; 4],
            shade: vec![0.5; 4],
        };
        let mut short = made(&key(0, 0, 0), &Ok(s));
        let at = short.len() - 4 * 4 - 8;
        short[at..at + 8].copy_from_slice(&3u64.to_le_bytes());
        short.truncate(short.len() - 4);
        assert!(read_made(&short).is_err());
    }
}
