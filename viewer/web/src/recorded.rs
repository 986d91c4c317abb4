//! A store source that remembers what it read while a reader opened the store, and answers those
//! reads again. The page's tile makers (web workers) read the store; the first one to open it
//! records the metadata it read, and the page and the other makers open the same store from that
//! record: one set of metadata requests for the page, none of them on the page's own thread.

use std::collections::HashMap;
use std::io;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{Arc, Mutex};

use sc_store::StoreSource;

use crate::wire::{Reader, Writer};

/// A read: which call, its key, its numbers (limit; suffix length; offset and length).
type Read = (u8, String, u64, u64);

const GET: u8 = 0;
const SUFFIX: u8 = 1;
const RANGE: u8 = 2;

/// What a read gave.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Got {
    /// No such object.
    Missing,
    /// The object, or the range asked for.
    Bytes(Vec<u8>),
    /// The object's size and its last bytes.
    Suffix(u64, Vec<u8>),
}

/// Answers recorded reads from the record and all others from `inner`; records what `inner`
/// answers until [`Recorded::stop`].
#[derive(Debug)]
pub struct Recorded {
    base: String,
    inner: Option<Arc<dyn StoreSource>>,
    record: Mutex<HashMap<Read, Got>>,
    recording: AtomicBool,
}

impl Recorded {
    /// Over the store at `base` (its URL, for messages): reads in `record` (as [`Self::record`]
    /// wrote it) answered from there, others from `inner`; without `inner` those are errors.
    pub fn new(
        base: &str,
        inner: Option<Arc<dyn StoreSource>>,
        record: Option<&[u8]>,
    ) -> Result<Self, String> {
        let record = match record {
            Some(b) => read_record(b).map_err(|e| format!("the store's record: {e}"))?,
            None => HashMap::new(),
        };
        Ok(Self {
            base: base.trim_end_matches('/').to_string(),
            inner,
            record: Mutex::new(record),
            recording: AtomicBool::new(true),
        })
    }

    /// Records nothing more (what was recorded is kept and still answered).
    pub fn stop(&self) {
        self.recording.store(false, Relaxed);
    }

    /// The reads recorded, as bytes for [`Self::new`].
    pub fn record(&self) -> Vec<u8> {
        let record = self.record.lock().unwrap_or_else(|e| e.into_inner());
        let mut reads: Vec<_> = record.iter().collect();
        reads.sort_by(|a, b| a.0.cmp(b.0));
        let mut w = Writer::default();
        w.u64(reads.len() as u64);
        for ((call, key, a, b), got) in reads {
            w.u8(*call);
            w.bytes(key.as_bytes());
            w.u64(*a);
            w.u64(*b);
            match got {
                Got::Missing => w.u8(0),
                Got::Bytes(v) => {
                    w.u8(1);
                    w.bytes(v);
                }
                Got::Suffix(size, v) => {
                    w.u8(2);
                    w.u64(*size);
                    w.bytes(v);
                }
            }
        }
        w.0
    }

    fn answer(
        &self,
        read: Read,
        fetch: impl FnOnce(&dyn StoreSource) -> io::Result<Got>,
    ) -> io::Result<Got> {
        if let Some(got) = self
            .record
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&read)
        {
            return Ok(got.clone());
        }
        let Some(inner) = &self.inner else {
            return Err(io::Error::other(format!(
                "{}: not read when the store was opened (the page's tile makers read the store)",
                self.name_of(&read.1).display()
            )));
        };
        let got = fetch(inner.as_ref())?;
        if self.recording.load(Relaxed) {
            self.record
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .insert(read, got.clone());
        }
        Ok(got)
    }
}

fn read_record(b: &[u8]) -> Result<HashMap<Read, Got>, String> {
    let mut r = Reader::new(b);
    let n = r.u64()?;
    let mut record = HashMap::new();
    for _ in 0..n {
        let call = r.u8()?;
        if call > RANGE {
            return Err(format!("a read of unknown kind {call}"));
        }
        let key = r.string()?;
        let (a, b) = (r.u64()?, r.u64()?);
        let got = match r.u8()? {
            0 => Got::Missing,
            1 => Got::Bytes(r.bytes()?.to_vec()),
            2 => Got::Suffix(r.u64()?, r.bytes()?.to_vec()),
            t => return Err(format!("an answer of unknown kind {t}")),
        };
        record.insert((call, key, a, b), got);
    }
    r.done()?;
    Ok(record)
}

fn odd(what: &str) -> io::Error {
    io::Error::other(format!("the store's record holds {what}"))
}

impl StoreSource for Recorded {
    fn name_of(&self, key: &str) -> PathBuf {
        PathBuf::from(format!("{}/{}", self.base, key.trim_start_matches('/')))
    }

    fn get(&self, key: &str, limit: u64) -> io::Result<Option<Vec<u8>>> {
        let got = self.answer((GET, key.to_string(), limit, 0), |s| {
            Ok(match s.get(key, limit)? {
                Some(v) => Got::Bytes(v),
                None => Got::Missing,
            })
        })?;
        match got {
            Got::Missing => Ok(None),
            Got::Bytes(v) => Ok(Some(v)),
            Got::Suffix(..) => Err(odd("a suffix for a whole object")),
        }
    }

    fn get_suffix(&self, key: &str, len: u64) -> io::Result<Option<(u64, Vec<u8>)>> {
        let got = self.answer((SUFFIX, key.to_string(), len, 0), |s| {
            Ok(match s.get_suffix(key, len)? {
                Some((size, v)) => Got::Suffix(size, v),
                None => Got::Missing,
            })
        })?;
        match got {
            Got::Missing => Ok(None),
            Got::Suffix(size, v) => Ok(Some((size, v))),
            Got::Bytes(_) => Err(odd("a whole object for a suffix")),
        }
    }

    fn get_range(&self, key: &str, offset: u64, len: u64) -> io::Result<Vec<u8>> {
        let got = self.answer((RANGE, key.to_string(), offset, len), |s| {
            s.get_range(key, offset, len).map(Got::Bytes)
        })?;
        match got {
            Got::Bytes(v) => Ok(v),
            _ => Err(odd("no bytes for a range")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    /// Objects in memory; counts the reads that reach it.
    #[derive(Debug, Default)]
    struct Memory {
        objects: HashMap<String, Vec<u8>>,
        reads: AtomicUsize,
    }

    impl StoreSource for Memory {
        fn name_of(&self, key: &str) -> PathBuf {
            PathBuf::from(key)
        }
        fn get(&self, key: &str, limit: u64) -> io::Result<Option<Vec<u8>>> {
            self.reads.fetch_add(1, Relaxed);
            match self.objects.get(key) {
                Some(v) if v.len() as u64 > limit => Err(io::Error::other("too big")),
                v => Ok(v.cloned()),
            }
        }
        fn get_suffix(&self, key: &str, len: u64) -> io::Result<Option<(u64, Vec<u8>)>> {
            self.reads.fetch_add(1, Relaxed);
            Ok(self.objects.get(key).map(|v| {
                let from = v.len().saturating_sub(len as usize);
                (v.len() as u64, v[from..].to_vec())
            }))
        }
        fn get_range(&self, key: &str, offset: u64, len: u64) -> io::Result<Vec<u8>> {
            self.reads.fetch_add(1, Relaxed);
            let v = self
                .objects
                .get(key)
                .ok_or_else(|| io::Error::other("none"))?;
            v.get(offset as usize..(offset + len) as usize)
                .map(<[u8]>::to_vec)
                .ok_or_else(|| io::Error::other("past the end"))
        }
    }

    #[test]
    fn what_was_read_while_recording_is_answered_again_without_the_source() {
        let mem = Arc::new(Memory {
            objects: [
                ("zarr.json".to_string(), b"{\"a\":1}".to_vec()),
                ("h/0/c/0/0".to_string(), (0..100u8).collect()),
            ]
            .into(),
            ..Memory::default()
        });
        let rec = Recorded::new("http://x/p.zarr/", Some(mem.clone()), None).expect("new");
        assert_eq!(
            rec.get("zarr.json", 100).expect("get"),
            Some(b"{\"a\":1}".to_vec())
        );
        assert_eq!(rec.get("none.json", 100).expect("get"), None);
        assert_eq!(
            rec.get_suffix("h/0/c/0/0", 10).expect("suffix"),
            Some((100, (90..100).collect()))
        );
        assert_eq!(
            rec.get_range("h/0/c/0/0", 5, 3).expect("range"),
            vec![5, 6, 7]
        );
        // read again: from the record
        assert_eq!(
            rec.get("zarr.json", 100).expect("get"),
            Some(b"{\"a\":1}".to_vec())
        );
        assert_eq!(mem.reads.load(Relaxed), 4);
        rec.stop();
        assert_eq!(rec.get_range("h/0/c/0/0", 0, 2).expect("range"), vec![0, 1]);
        let record = rec.record();
        // the page: the record only
        let page = Recorded::new("http://x/p.zarr", None, Some(&record)).expect("new");
        assert_eq!(
            page.get("zarr.json", 100).expect("get"),
            Some(b"{\"a\":1}".to_vec())
        );
        assert_eq!(page.get("none.json", 100).expect("get"), None);
        assert_eq!(
            page.get_suffix("h/0/c/0/0", 10)
                .expect("suffix")
                .expect("some")
                .0,
            100
        );
        assert_eq!(
            page.get_range("h/0/c/0/0", 5, 3).expect("range"),
            vec![5, 6, 7]
        );
        // recorded no more after stop, and a read with other numbers is another read
        let e = page.get_range("h/0/c/0/0", 0, 2).expect_err("not recorded");
        assert!(e.to_string().contains("http://x/p.zarr/h/0/c/0/0"), "{e}");
        assert!(page.get("zarr.json", 99).is_err());
        // another maker: the record, then its own source
        let maker =
            Recorded::new("http://x/p.zarr", Some(mem.clone()), Some(&record)).expect("new");
        let before = mem.reads.load(Relaxed);
        assert!(maker.get("zarr.json", 100).expect("get").is_some());
        assert_eq!(mem.reads.load(Relaxed), before);
        assert_eq!(
            maker.get_range("h/0/c/0/0", 0, 2).expect("range"),
            vec![0, 1]
        );
        assert_eq!(mem.reads.load(Relaxed), before + 1);
    }

    #[test]
    fn a_damaged_record_is_refused() {
        let mem = Arc::new(Memory {
            objects: [("zarr.json".to_string(), b"{}".to_vec())].into(),
            ..Memory::default()
        });
        let rec = Recorded::new("u", Some(mem), None).expect("new");
        rec.get("zarr.json", 10).expect("get");
        let b = rec.record();
        for cut in 0..b.len() {
            assert!(
                Recorded::new("u", None, Some(&b[..cut])).is_err(),
                "cut at {cut}"
            );
        }
    }
}
