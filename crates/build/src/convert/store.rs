//! Content store: tile contents handed from one stage to the next (region roots to the top
//! stage, top parents to theirs), kept in one file in the staging folder instead of memory, so
//! the levels above the regions hold only the parents being built and their children.

use super::ConvertError;
use super::spill_records::Codec;
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::tiling::TileKey;
use std::collections::HashMap;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::PathBuf;
use std::sync::Mutex;

/// Where one stored content lies.
#[derive(Debug, Clone, Copy)]
struct Entry {
    offset: u64,
    count: u64,
    radius: f64,
}

/// An append-only file of tile contents, read back by key.
#[derive(Debug)]
pub(super) struct ContentStore {
    path: PathBuf,
    codec: Codec,
    inner: Mutex<(std::fs::File, u64, HashMap<TileKey, Entry>)>,
}

impl ContentStore {
    /// A new, empty store at `path`.
    pub(super) fn create(path: PathBuf, codec: Codec) -> Result<ContentStore, ConvertError> {
        let file =
            std::fs::File::create(&path).map_err(super::io_err(&path, "creating content store"))?;
        Ok(ContentStore {
            path,
            codec,
            inner: Mutex::new((file, 0, HashMap::new())),
        })
    }

    /// Stores the content of `key` (its splats and clustering radius).
    pub(super) fn put(&self, key: TileKey, s: &Splats, radius: f64) -> Result<(), ConvertError> {
        let idx = vec![0u64; s.len()];
        let mut buf = Vec::with_capacity(s.len() * self.codec.record_bytes());
        self.codec
            .write_all(s, &idx, &mut buf)
            .map_err(super::io_err(&self.path, "writing content store"))?;
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let (file, end, index) = &mut *g;
        file.write_all(&buf)
            .map_err(super::io_err(&self.path, "writing content store"))?;
        index.insert(
            key,
            Entry {
                offset: *end,
                count: s.len() as u64,
                radius,
            },
        );
        *end += buf.len() as u64;
        Ok(())
    }

    /// The content of `key` and its radius (`None` when never stored).
    pub(super) fn get(&self, key: TileKey) -> Result<Option<(Splats, f64)>, ConvertError> {
        let e = {
            let g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
            match g.2.get(&key) {
                Some(e) => *e,
                None => return Ok(None),
            }
        };
        let err = |source| ConvertError::Io {
            path: self.path.clone(),
            what: "reading content store",
            source,
        };
        let mut f = std::fs::File::open(&self.path).map_err(err)?;
        f.seek(SeekFrom::Start(e.offset)).map_err(err)?;
        let mut buf = vec![0u8; e.count as usize * self.codec.record_bytes()];
        f.read_exact(&mut buf).map_err(err)?;
        let mut s = Splats::with_capacity(self.codec.degree(), e.count as usize);
        let mut idx = Vec::with_capacity(e.count as usize);
        self.codec.decode(&buf, &mut s, &mut idx);
        Ok(Some((s, e.radius)))
    }
}
