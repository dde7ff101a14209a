//! Camera-path recording shared by the native and web viewers: poses in the tileset frame kept
//! at most every 1/12 s, up to one hour, written as a `splat2tiles-trace: 1` CSV (`Trace::to_csv`).

use std::path::Path;

use anyhow::{Context, bail};
use glam::{DMat4, DVec3};
use splat2tiles_stream::geom::ViewPose;
use splat2tiles_stream::trace::{TRACE_HZ, Trace};

/// Most poses a recording keeps: one hour at 12 Hz (32 bytes each, about 1.4 MB). Later poses
/// are dropped and the CSV says so (`# truncated: ...`).
pub const MAX_POSES: usize = 3600 * TRACE_HZ as usize;

/// A camera path being recorded.
#[derive(Debug, Clone)]
pub struct Recorder {
    trace: Trace,
    /// Shortest time between two kept poses (0: keep every pose given).
    min_interval_s: f64,
    /// Poses dropped after [`MAX_POSES`].
    dropped: usize,
}

impl Recorder {
    /// An empty recording that keeps a pose when at least `min_interval_s` seconds have passed
    /// since the last one kept; `headers` follow `splat2tiles-trace: 1` and `kind: recorded`.
    pub fn new(min_interval_s: f64, headers: &[(&str, String)]) -> Recorder {
        let mut all = vec![
            ("splat2tiles-trace".to_string(), "1".to_string()),
            ("kind".to_string(), "recorded".to_string()),
        ];
        all.extend(headers.iter().map(|(k, v)| (k.to_string(), v.clone())));
        Recorder {
            trace: Trace {
                headers: all,
                poses: Vec::new(),
            },
            min_interval_s: min_interval_s.max(0.0),
            dropped: 0,
        }
    }

    /// A recorder at the committed traces' rate (12 Hz).
    pub fn at_trace_rate(headers: &[(&str, String)]) -> Recorder {
        // A hair under 1/12 s, so a 60 Hz display's frames keep 12 of every 60.
        Recorder::new(1.0 / TRACE_HZ - 1e-3, headers)
    }

    /// Offers the pose at `pose.t` seconds (tileset frame); kept when it is finite, not earlier
    /// than the last pose, far enough from it in time, and the recording is not full.
    pub fn record(&mut self, pose: ViewPose) {
        let finite = pose.t.is_finite()
            && pose.pos.is_finite()
            && pose.yaw.is_finite()
            && pose.pitch.is_finite();
        if !finite {
            return;
        }
        if let Some(last) = self.trace.poses.last()
            && pose.t < last.t + self.min_interval_s
        {
            return;
        }
        if self.trace.poses.len() >= MAX_POSES {
            self.dropped += 1;
            return;
        }
        self.trace.poses.push(pose);
    }

    /// Poses kept so far.
    pub fn len(&self) -> usize {
        self.trace.poses.len()
    }

    /// No pose kept yet.
    pub fn is_empty(&self) -> bool {
        self.trace.poses.is_empty()
    }

    /// Seconds from the first to the last pose kept.
    pub fn duration(&self) -> f64 {
        self.trace.duration()
    }

    /// Forgets every pose (the headers stay).
    pub fn clear(&mut self) {
        self.trace.poses.clear();
        self.dropped = 0;
    }

    /// The recording as a trace (with a `truncated` header when poses were dropped).
    pub fn trace(&self) -> Trace {
        let mut t = self.trace.clone();
        if self.dropped > 0 {
            t.headers.push((
                "truncated".into(),
                format!(
                    "{} later poses dropped after {MAX_POSES} (one hour at 12 Hz)",
                    self.dropped
                ),
            ));
        }
        t
    }

    /// The recording as `splat2tiles-trace: 1` CSV text.
    pub fn csv(&self) -> String {
        self.trace().to_csv()
    }
}

/// The pose (tileset frame, z up) of a camera whose `world_from_camera` is given in world
/// coordinates, `root` mapping the tileset frame to world; yaw from +x towards +y, pitch up.
pub fn pose_of(t: f64, world_from_camera: DMat4, root: DMat4) -> ViewPose {
    let local = root.inverse() * world_from_camera;
    let pos = local.w_axis.truncate();
    let fwd = local.z_axis.truncate().normalize_or(DVec3::X);
    ViewPose::looking_at(t, pos, pos + fwd)
}

/// Refuses a `--record PATH` that cannot be written: a folder, or one inside a missing folder.
pub fn check_path(path: &Path) -> anyhow::Result<()> {
    if path.is_dir() {
        bail!("--record {}: is a folder, not a file", path.display());
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        bail!(
            "--record {}: no folder {}",
            path.display(),
            parent.display()
        );
    }
    Ok(())
}

/// Writes `text` to `path` whole or not at all: into a temporary file beside it, then renamed
/// over it. Refuses a folder.
pub fn write_atomic(path: &Path, text: &str) -> anyhow::Result<()> {
    check_path(path)?;
    let name = path
        .file_name()
        .with_context(|| format!("{}: no file name", path.display()))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".{}.tmp", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let written = std::fs::write(&tmp, text)
        .and_then(|_| std::fs::File::open(&tmp)?.sync_all())
        .and_then(|_| std::fs::rename(&tmp, path));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("{}: cannot write", path.display()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(t: f64) -> ViewPose {
        ViewPose {
            t,
            pos: DVec3::new(t, 2.0, 3.0),
            yaw: 0.5,
            pitch: -0.25,
        }
    }

    #[test]
    fn keeps_twelve_poses_a_second_and_round_trips_through_the_csv() {
        let mut r = Recorder::at_trace_rate(&[("fov_y_deg", "50".into())]);
        // 2 s of a 60 Hz display.
        for k in 0..=120 {
            r.record(pose(k as f64 / 60.0));
        }
        r.record(pose(f64::NAN));
        r.record(pose(0.5)); // back in time
        assert_eq!(r.len(), 25, "{:?}", r.trace().poses);
        let back = Trace::from_csv(&r.csv()).unwrap();
        assert_eq!(back.header("kind"), Some("recorded"));
        assert_eq!(back.header("fov_y_deg"), Some("50"));
        assert_eq!(back.poses.len(), 25);
        let (a, b) = (back.poses[3], r.trace().poses[3]);
        assert!((a.t - b.t).abs() < 1e-4 && (a.pos - b.pos).length() < 1e-4);
        assert!((a.yaw - b.yaw).abs() < 1e-4 && (a.pitch - b.pitch).abs() < 1e-4);
        r.clear();
        assert!(r.is_empty() && r.duration() == 0.0);
    }

    #[test]
    fn stops_at_one_hour_and_says_so() {
        let mut r = Recorder::new(0.0, &[]);
        for k in 0..MAX_POSES + 5 {
            r.record(pose(k as f64));
        }
        assert_eq!(r.len(), MAX_POSES);
        let t = r.trace();
        assert!(t.header("truncated").unwrap().starts_with("5 later poses"));
    }

    #[test]
    fn pose_of_inverts_the_root_transform() {
        let p = ViewPose {
            t: 1.0,
            pos: DVec3::new(1.0, -2.0, 3.0),
            yaw: 2.0,
            pitch: 0.3,
        };
        let root = DMat4::from_rotation_x(1.0) * DMat4::from_translation(DVec3::new(5.0, 6.0, 7.0));
        let q = pose_of(1.0, root * p.world_from_camera(), root);
        assert!((q.pos - p.pos).length() < 1e-9);
        assert!((q.yaw - p.yaw).abs() < 1e-9 && (q.pitch - p.pitch).abs() < 1e-9);
    }

    #[test]
    fn writes_whole_files_and_refuses_folders() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("path.csv");
        write_atomic(&f, "one").unwrap();
        write_atomic(&f, "two").unwrap();
        assert_eq!(std::fs::read_to_string(&f).unwrap(), "two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let e = write_atomic(dir.path(), "x").unwrap_err();
        assert!(format!("{e:#}").contains("is a folder"), "{e:#}");
        let e = check_path(&dir.path().join("missing/path.csv")).unwrap_err();
        assert!(format!("{e:#}").contains("no folder"), "{e:#}");
    }
}
