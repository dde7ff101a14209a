//! The file every finished output folder carries (`.splat2tiles-output.json`): it says the folder
//! is ours and lists the top-level entries we wrote, so a later run may replace exactly those.

use std::collections::BTreeSet;
use std::path::Path;

/// Name of the marker file inside an output folder.
pub const MARKER: &str = ".splat2tiles-output.json";

/// What the marker of an earlier output says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Marker {
    /// Top-level entries the earlier run wrote (file and folder names).
    pub entries: BTreeSet<String>,
}

#[derive(serde::Serialize, serde::Deserialize)]
struct MarkerJson {
    generator: String,
    entries: Vec<String>,
}

/// Most bytes read of a marker file (it lists a handful of names).
const MAX_MARKER_BYTES: u64 = 64 * 1024;

/// Reads the marker of folder `dir`; `None` when it is absent or not one of ours.
pub fn read(dir: &Path) -> Option<Marker> {
    use std::io::Read;
    let f = std::fs::File::open(dir.join(MARKER)).ok()?;
    let mut text = Vec::new();
    f.take(MAX_MARKER_BYTES).read_to_end(&mut text).ok()?;
    let m: MarkerJson = serde_json::from_slice(&text).ok()?;
    m.generator.starts_with("splat2tiles").then(|| Marker {
        entries: m.entries.into_iter().collect(),
    })
}

/// Writes the marker into `dir`, listing its current top-level entries.
pub fn write(dir: &Path) -> std::io::Result<()> {
    let mut entries = Vec::new();
    for e in std::fs::read_dir(dir)? {
        let name = e?.file_name().to_string_lossy().into_owned();
        if name != MARKER {
            entries.push(name);
        }
    }
    entries.sort();
    let m = MarkerJson {
        generator: format!("splat2tiles {}", env!("CARGO_PKG_VERSION")),
        entries,
    };
    let json = serde_json::to_vec_pretty(&m).map_err(std::io::Error::other)?;
    std::fs::write(dir.join(MARKER), json)
}
