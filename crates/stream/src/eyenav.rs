//! Reader for the EyeNavGS head traces (`data/navigation-traces/`) and their placement into
//! our z-up scenes as [`Trace`]s: real people walking and turning, at street level in a city.
//!
//! Dataset: Ding, Lee, Zhu, Guan, Sun, Hsu, Liu, "EyeNavGS: A 6-DoF Navigation Dataset and
//! Record-n-Replay Software for Real-World 3DGS Scenes in VR", arXiv:2506.02380, 2025 (Apache 2.0;
//! `data/navigation-traces/README.md`): 10 scenes x 22 users, head poses at 12 Hz.
//!
//! Input rows are `t_s,x,y,z,qx,qy,qz,qw` in Unity's frame (y up, left-handed, metres after the
//! dataset's per-scene scale); the camera looks along +z of the quaternion. Swapping Unity's y and
//! z gives a right-handed z-up frame (x east, y north, z up): `(x, y, z)_ours = (x, z, y)_unity`,
//! applied to positions and to the viewing direction `q * (0, 0, 1)`, from which yaw (from +x
//! towards +y) and pitch (upwards) follow. Roll is dropped (our poses have none).
//!
//! [`Placement`] puts a session into a scene: the session's first horizontal position goes to
//! `anchor`, horizontal offsets are turned by `heading_deg` about z and scaled by `h_scale`, and the
//! height is `anchor.z + eye_height_m + (y - median y of the session)` (the head's own bobbing and
//! crouching kept at scale 1). The positions are head positions in the room the user walked in;
//! `scene_setting.csv` only says how the 3DGS model was scaled, tilted and offset under that room
//! (the head frame is already level and metric), so it changes nothing in the placement and is
//! read for the provenance headers ([`SceneSetting`]).

use super::trace::Trace;
use crate::geom::ViewPose;
use glam::{DQuat, DVec3};
use std::io::Read;
use std::path::Path;

/// The ten EyeNavGS scenes in the shared copy.
pub const SCENES: [&str; 10] = [
    "alameda", "berlin", "bicycle", "nyc", "playroom", "room", "stump", "train", "treehill",
    "truck",
];

/// Largest trace file read (the largest shared one is about 200 KB).
pub const MAX_FILE_BYTES: u64 = 32 << 20;

/// Median horizontal walking speed of the dataset in m/s (`navigation-traces/README.md`).
pub const DATASET_MEDIAN_SPEED: f64 = 0.23;

/// Where and how a session is put into a scene (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Scene position (tileset frame, z up, metres) of the session's first horizontal position;
    /// `anchor.z` is the ground height there.
    pub anchor: DVec3,
    /// Rotation of the session's horizontal offsets about z, degrees (counter-clockwise).
    pub heading_deg: f64,
    /// Horizontal scale applied to the session's offsets from its start.
    pub h_scale: f64,
    /// Eye height above `anchor.z` at the session's median head height, metres.
    pub eye_height_m: f64,
}

impl Default for Placement {
    /// At the origin, unrotated, scale 1, eyes at 1.7 m.
    fn default() -> Self {
        Placement {
            anchor: DVec3::ZERO,
            heading_deg: 0.0,
            h_scale: 1.0,
            eye_height_m: 1.7,
        }
    }
}

/// One raw EyeNavGS sample in Unity's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawSample {
    /// Seconds from the session start.
    pub t: f64,
    /// Head position (Unity: y up, left-handed).
    pub pos: [f64; 3],
    /// Head orientation `x, y, z, w` (normalised on reading).
    pub quat: [f64; 4],
}

/// A session read from one CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// Scene name (the file's directory, e.g. `nyc`).
    pub scene: String,
    /// User id from the file name (`user101_nyc.csv` -> `user101`).
    pub user: String,
    /// Samples sorted by time.
    pub samples: Vec<RawSample>,
}

/// Reads a whole file of at most `limit` bytes; errors name the file.
pub fn read_bounded(path: &Path, limit: u64) -> Result<String, String> {
    let f = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut buf = Vec::new();
    f.take(limit + 1)
        .read_to_end(&mut buf)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if buf.len() as u64 > limit {
        return Err(format!(
            "{}: larger than the {limit}-byte limit for this kind of file",
            path.display()
        ));
    }
    String::from_utf8(buf).map_err(|e| {
        format!(
            "{}: byte offset {}: not UTF-8",
            path.display(),
            e.utf8_error().valid_up_to()
        )
    })
}

/// Parses an EyeNavGS CSV; `name` (the file) is used in errors, which give the line number.
pub fn parse_session(text: &str, name: &str, scene: &str, user: &str) -> Result<Session, String> {
    let mut lines = text.lines().enumerate();
    let header = lines.next().map(|(_, l)| l.trim()).unwrap_or("");
    if header.trim_start_matches('\u{feff}') != "t_s,x,y,z,qx,qy,qz,qw" {
        return Err(format!(
            "{name}: line 1: expected the header 't_s,x,y,z,qx,qy,qz,qw'"
        ));
    }
    let mut samples: Vec<RawSample> = Vec::new();
    for (n, line) in lines {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let ln = n + 1;
        let mut v = [0f64; 8];
        let mut k = 0usize;
        for field in line.split(',') {
            if k == 8 {
                return Err(format!("{name}: line {ln}: more than 8 fields"));
            }
            v[k] = field
                .trim()
                .parse::<f64>()
                .map_err(|e| format!("{name}: line {ln}: field {}: {e}", k + 1))?;
            if !v[k].is_finite() {
                return Err(format!("{name}: line {ln}: field {} is not finite", k + 1));
            }
            k += 1;
        }
        if k != 8 {
            return Err(format!("{name}: line {ln}: expected 8 fields, found {k}"));
        }
        if let Some(prev) = samples.last()
            && v[0] < prev.t
        {
            return Err(format!("{name}: line {ln}: time goes backwards"));
        }
        let q = DQuat::from_xyzw(v[4], v[5], v[6], v[7]);
        let len = q.length();
        if !len.is_finite() || len <= 1e-6 {
            return Err(format!("{name}: line {ln}: zero or overflowing quaternion"));
        }
        if let Some(first) = samples.first()
            && !(v[0] - first.t).is_finite()
        {
            return Err(format!("{name}: line {ln}: time out of range"));
        }
        let q = q / len;
        samples.push(RawSample {
            t: v[0],
            pos: [v[1], v[2], v[3]],
            quat: [q.x, q.y, q.z, q.w],
        });
    }
    if samples.len() < 2 {
        return Err(format!("{name}: fewer than 2 samples"));
    }
    Ok(Session {
        scene: scene.to_string(),
        user: user.to_string(),
        samples,
    })
}

/// Reads `path` (`.../SCENE/USER_SCENE.csv`); the scene is the parent directory's name.
pub fn read_session(path: &Path) -> Result<Session, String> {
    let text = read_bounded(path, MAX_FILE_BYTES)?;
    let scene = path
        .parent()
        .and_then(|p| p.file_name())
        .and_then(|s| s.to_str())
        .unwrap_or("");
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    let user = stem.split('_').next().unwrap_or(stem);
    parse_session(&text, &path.display().to_string(), scene, user)
}

/// Session files of `scene` under `root` (the shared `navigation-traces/`), sorted by name.
pub fn session_files(root: &Path, scene: &str) -> Result<Vec<std::path::PathBuf>, String> {
    let dir = root.join(scene);
    let rd = std::fs::read_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut out = vec![];
    for e in rd {
        let e = e.map_err(|e| format!("{}: {e}", dir.display()))?;
        let p = e.path();
        if p.extension().is_some_and(|x| x == "csv") {
            out.push(p);
        }
        if out.len() > 10_000 {
            return Err(format!("{}: more than 10000 files", dir.display()));
        }
    }
    out.sort();
    Ok(out)
}

/// Unity (y up, left-handed) to ours (z up, right-handed): swap y and z.
pub fn unity_to_zup(v: [f64; 3]) -> DVec3 {
    DVec3::new(v[0], v[2], v[1])
}

/// Viewing direction of a Unity orientation in our frame.
pub fn forward_zup(quat: [f64; 4]) -> DVec3 {
    let q = DQuat::from_xyzw(quat[0], quat[1], quat[2], quat[3]);
    let f = q * DVec3::Z;
    unity_to_zup(f.to_array())
}

impl Session {
    /// Median head height (Unity y) of the session.
    pub fn median_height(&self) -> f64 {
        let mut y: Vec<f64> = self.samples.iter().map(|s| s.pos[1]).collect();
        let mid = y.len() / 2;
        let (_, m, _) = y.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        *m
    }

    /// Duration in seconds.
    pub fn duration(&self) -> f64 {
        match (self.samples.first(), self.samples.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        }
    }

    /// The session placed by `pl` (see the module docs) as a trace of `scene` with `split`; the
    /// time starts at 0.
    pub fn place(&self, pl: &Placement, scene: &str, split: &str) -> Trace {
        let first = self.samples[0];
        let t0 = first.t;
        let start = unity_to_zup(first.pos);
        let y_mid = self.median_height();
        let (s, c) = pl.heading_deg.to_radians().sin_cos();
        let poses = self
            .samples
            .iter()
            .map(|smp| {
                let p = unity_to_zup(smp.pos);
                let dx = (p.x - start.x) * pl.h_scale;
                let dy = (p.y - start.y) * pl.h_scale;
                let pos = DVec3::new(
                    pl.anchor.x + c * dx - s * dy,
                    pl.anchor.y + s * dx + c * dy,
                    pl.anchor.z + pl.eye_height_m + (smp.pos[1] - y_mid),
                );
                let f = forward_zup(smp.quat);
                let f = DVec3::new(c * f.x - s * f.y, s * f.x + c * f.y, f.z);
                ViewPose {
                    t: smp.t - t0,
                    pos,
                    yaw: f.y.atan2(f.x),
                    pitch: f.z.clamp(-1.0, 1.0).asin(),
                }
            })
            .collect();
        let headers = [
            ("splat2tiles-trace", "1".to_string()),
            ("scene", scene.to_string()),
            ("kind", "eyenav".to_string()),
            ("seed", "0".to_string()),
            ("split", split.to_string()),
            ("fov_y_deg", "50".to_string()),
            ("aspect", "1.7778".to_string()),
            (
                "source",
                format!("EyeNavGS {}/{}_{}.csv", self.scene, self.user, self.scene),
            ),
            (
                "placement",
                format!(
                    "anchor {:.3} {:.3} {:.3}, heading {:.1} deg, horizontal x{}, eye {} m",
                    pl.anchor.x,
                    pl.anchor.y,
                    pl.anchor.z,
                    pl.heading_deg,
                    pl.h_scale,
                    pl.eye_height_m
                ),
            ),
        ];
        Trace {
            headers: headers
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect(),
            poses,
        }
    }
}

/// One row of `scene_setting.csv`: the dataset's tilt correction, scale and start position.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSetting {
    /// Scene name.
    pub scene: String,
    /// Tilt correction `x, y, z, w`.
    pub quat: [f64; 4],
    /// Scale applied to the 3DGS model.
    pub scale: f64,
    /// Initial position (Unity frame).
    pub initial_position: [f64; 3],
}

/// Splits a CSV line with `"..."` fields (no escaped quotes inside).
fn split_quoted(line: &str) -> Option<Vec<&str>> {
    let mut out = vec![];
    let mut rest = line;
    loop {
        if let Some(r) = rest.strip_prefix('"') {
            let end = r.find('"')?;
            out.push(&r[..end]);
            rest = &r[end + 1..];
        } else {
            let end = rest.find(',').unwrap_or(rest.len());
            out.push(&rest[..end]);
            rest = &rest[end..];
        }
        match rest.strip_prefix(',') {
            Some(r) => rest = r,
            None if rest.is_empty() => return Some(out),
            None => return None,
        }
    }
}

fn floats<const N: usize>(s: &str) -> Option<[f64; N]> {
    let mut out = [0.0; N];
    let mut k = 0;
    for f in s.split(',') {
        if k == N {
            return None;
        }
        out[k] = f.trim().parse::<f64>().ok().filter(|v| v.is_finite())?;
        k += 1;
    }
    (k == N).then_some(out)
}

/// Parses `scene_setting.csv` (`Scene_Name,Quaternion,Scale,Initial_Position`); errors name
/// `name` and the line.
pub fn parse_scene_settings(text: &str, name: &str) -> Result<Vec<SceneSetting>, String> {
    let mut lines = text.lines().enumerate();
    let header = lines.next().map(|(_, l)| l.trim()).unwrap_or("");
    if header.trim_start_matches('\u{feff}') != "Scene_Name,Quaternion,Scale,Initial_Position" {
        return Err(format!(
            "{name}: line 1: expected 'Scene_Name,Quaternion,Scale,Initial_Position'"
        ));
    }
    let mut out = vec![];
    for (n, line) in lines {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let bad = |what: &str| format!("{name}: line {}: {what}", n + 1);
        let f = split_quoted(line).ok_or_else(|| bad("unbalanced quotes"))?;
        let [scene, q, scale, pos] = f[..] else {
            return Err(bad("expected 4 fields"));
        };
        out.push(SceneSetting {
            scene: scene.trim().to_string(),
            quat: floats::<4>(q).ok_or_else(|| bad("quaternion: expected 4 numbers"))?,
            scale: floats::<1>(scale).ok_or_else(|| bad("scale: expected a number"))?[0],
            initial_position: floats::<3>(pos)
                .ok_or_else(|| bad("initial position: expected 3 numbers"))?,
        });
    }
    Ok(out)
}

/// Reads `ROOT/scene_setting.csv`.
pub fn read_scene_settings(root: &Path) -> Result<Vec<SceneSetting>, String> {
    let path = root.join("scene_setting.csv");
    let text = read_bounded(&path, 1 << 20)?;
    parse_scene_settings(&text, &path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    const CSV: &str = "t_s,x,y,z,qx,qy,qz,qw\n\
        0.0000,0.1735,0.5580,-1.5210,0.16699,0.20699,-0.00900,0.96394\n\
        0.0833,0.1740,0.5560,-1.5195,0.15592,0.22502,-0.00700,0.96177\n\
        0.1667,1.1735,0.6560,-1.5210,0,0,0,1\n";

    fn shared() -> std::path::PathBuf {
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/navigation-traces")
    }

    #[test]
    fn axes_and_angles() {
        // Identity: Unity +z (forward) is our +y (north): yaw 90 deg, pitch 0.
        let f = forward_zup([0.0, 0.0, 0.0, 1.0]);
        assert!((f - DVec3::Y).length() < 1e-12);
        // 90 deg about Unity's y (up) turns +z to +x: our +x, yaw 0.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let f = forward_zup([0.0, h, 0.0, h]);
        assert!((f - DVec3::X).length() < 1e-12, "{f}");
        // Pitch down 30 deg about Unity's x: forward gets a negative Unity y, our -z.
        let q = DQuat::from_rotation_x(30f64.to_radians());
        let f = forward_zup([q.x, q.y, q.z, q.w]);
        assert!((f.z.asin().to_degrees() + 30.0).abs() < 1e-9, "{f}");
        assert_eq!(unity_to_zup([1.0, 2.0, 3.0]), DVec3::new(1.0, 3.0, 2.0));
    }

    #[test]
    fn placement_scales_rotates_and_sets_eye_height() {
        let s = parse_session(CSV, "t.csv", "nyc", "user1").unwrap();
        let pl = Placement {
            anchor: DVec3::new(100.0, 50.0, 2.0),
            heading_deg: 90.0,
            h_scale: 6.0,
            eye_height_m: 1.7,
        };
        let t = s.place(&pl, "city", "test");
        assert_eq!(t.poses.len(), 3);
        assert!((t.poses[0].pos - DVec3::new(100.0, 50.0, 2.0 + 1.7)).length() < 1e-9);
        // Third sample: +1 m Unity x (our x), turned 90 deg -> our +y, scaled x6; head 0.1 m
        // above the median (0.558).
        let p = t.poses[2].pos;
        assert!(
            (p - DVec3::new(100.0, 56.0, 3.7 + 0.098)).length() < 1e-9,
            "{p}"
        );
        // Identity orientation looks along our +y, turned 90 deg: -x, yaw 180.
        assert!((t.poses[2].yaw.abs() - std::f64::consts::PI).abs() < 1e-9);
        assert_eq!(t.header("kind"), Some("eyenav"));
        assert_eq!(t.header("split"), Some("test"));
        // Round trip through the trace format.
        let back = Trace::from_csv(&t.to_csv()).unwrap();
        assert_eq!(back.poses.len(), 3);
    }

    #[test]
    fn hostile_inputs_are_errors_naming_the_line() {
        let cases = [
            ("", "line 1"),
            ("x,y\n", "line 1"),
            ("t_s,x,y,z,qx,qy,qz,qw\n", "fewer than 2"),
            ("t_s,x,y,z,qx,qy,qz,qw\n0,1,2,3,0,0,0,1\n1,1,2\n", "line 3"),
            (
                "t_s,x,y,z,qx,qy,qz,qw\n0,1,2,3,0,0,0,1\n1,1,2,3,0,0,0,1,9\n",
                "line 3",
            ),
            (
                "t_s,x,y,z,qx,qy,qz,qw\n0,1,2,3,0,0,0,1\n1,NaN,2,3,0,0,0,1\n",
                "line 3",
            ),
            (
                "t_s,x,y,z,qx,qy,qz,qw\n0,1,2,3,0,0,0,1\n1,inf,2,3,0,0,0,1\n",
                "line 3",
            ),
            (
                "t_s,x,y,z,qx,qy,qz,qw\n1,1,2,3,0,0,0,1\n0,1,2,3,0,0,0,1\n",
                "backwards",
            ),
            (
                "t_s,x,y,z,qx,qy,qz,qw\n0,1,2,3,0,0,0,1\n1,1,2,3,0,0,0,0\n",
                "zero or",
            ),
            (
                "t_s,x,y,z,qx,qy,qz,qw\n0,1,2,3,0,0,0,1\n1,1,2,x,0,0,0,1\n",
                "field 4",
            ),
        ];
        for (text, want) in cases {
            let e = parse_session(text, "bad.csv", "s", "u").unwrap_err();
            assert!(
                e.starts_with("bad.csv") && e.contains(want),
                "{text:?}: {e}"
            );
        }
    }

    /// Random text and mutated valid files never panic (they parse or name a line).
    #[test]
    fn random_and_mutated_inputs_never_panic() {
        let mut rng = splat2tiles_core::rng::SplitMix64::new(5);
        let alphabet = b"0123456789.,-+eEnaNifINF \t\n\"xqt_s";
        for _ in 0..2000 {
            let len = rng.below(200);
            let junk: String = (0..len)
                .map(|_| alphabet[rng.below(alphabet.len())] as char)
                .collect();
            let mut mutated = CSV.as_bytes().to_vec();
            for _ in 0..3 {
                let i = rng.below(mutated.len());
                mutated[i] = alphabet[rng.below(alphabet.len())];
            }
            let mutated = String::from_utf8_lossy(&mutated).into_owned();
            for text in [
                junk.clone(),
                format!("t_s,x,y,z,qx,qy,qz,qw\n{junk}"),
                mutated,
            ] {
                if let Err(e) = parse_session(&text, "f.csv", "s", "u") {
                    assert!(e.starts_with("f.csv"), "{e}");
                }
                let _ = parse_scene_settings(&text, "s.csv");
            }
        }
    }

    #[test]
    fn oversized_file_is_refused_before_reading_it_all() {
        let dir = std::env::temp_dir().join(format!("eyenav-big-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("big.csv");
        std::fs::write(&p, vec![b'1'; 4096]).unwrap();
        let e = read_bounded(&p, 1000).unwrap_err();
        assert!(e.contains("big.csv") && e.contains("limit"), "{e}");
        std::fs::write(&p, [b't', 0xff, 0xfe]).unwrap();
        let e = read_bounded(&p, 1000).unwrap_err();
        assert!(e.contains("byte offset 1"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn scene_settings_parse_and_reject_garbage() {
        let ok = "Scene_Name,Quaternion,Scale,Initial_Position\n\
                  nyc,\"-0.1483, 0.0000, 0.0000, 0.9888\",0.64,\"-1.6,4.4,4\"\n";
        let s = parse_scene_settings(ok, "s.csv").unwrap();
        assert_eq!(s[0].scene, "nyc");
        assert_eq!(s[0].scale, 0.64);
        assert_eq!(s[0].initial_position, [-1.6, 4.4, 4.0]);
        for bad in [
            "nope\n",
            "Scene_Name,Quaternion,Scale,Initial_Position\nnyc,\"1,2,3\",1,\"0,0,0\"\n",
            "Scene_Name,Quaternion,Scale,Initial_Position\nnyc,\"1,2,3,4\",x,\"0,0,0\"\n",
            "Scene_Name,Quaternion,Scale,Initial_Position\nnyc,\"1,2,3,4,1,\"0,0,0\"\n",
            "Scene_Name,Quaternion,Scale,Initial_Position\nnyc,\"1,2,3,4\",1\n",
        ] {
            let e = parse_scene_settings(bad, "s.csv").unwrap_err();
            assert!(e.starts_with("s.csv: line"), "{bad:?}: {e}");
        }
    }

    /// The shared copy (`data/navigation-traces/README.md`): every file of two scenes reads,
    /// at 12 Hz, with heads mostly level (median |pitch| under 25 deg; some users look up at
    /// the buildings much of the time) and walking speeds near the
    /// README's median.
    #[test]
    fn shared_traces_read() {
        let root = shared();
        if !root.exists() {
            eprintln!("skipped: {} missing", root.display());
            return;
        }
        let settings = read_scene_settings(&root).unwrap();
        for scene in SCENES {
            assert!(settings.iter().any(|s| s.scene == scene), "{scene}");
        }
        let (mut speeds, mut pitches) = (vec![], vec![]);
        for scene in ["nyc", "truck"] {
            let files = session_files(&root, scene).unwrap();
            assert_eq!(files.len(), 22, "{scene}");
            for f in files {
                let s = read_session(&f).unwrap();
                assert_eq!(s.scene, scene);
                let dt = s.duration() / (s.samples.len() - 1) as f64;
                assert!((dt - 1.0 / 12.0).abs() < 0.01, "{}: {dt}", f.display());
                let t = s.place(&Placement::default(), "x", "test");
                pitches.extend(t.poses.iter().map(|p| p.pitch.abs()));
                let d: f64 = t
                    .poses
                    .windows(2)
                    .map(|w| (w[1].pos - w[0].pos).truncate().length())
                    .sum();
                speeds.push(d / t.duration());
            }
        }
        speeds.sort_by(f64::total_cmp);
        let med = speeds[speeds.len() / 2];
        assert!((0.1..0.4).contains(&med), "median speed {med}");
        pitches.sort_by(f64::total_cmp);
        let med = pitches[pitches.len() / 2].to_degrees();
        assert!(med < 25.0, "median |pitch| {med} deg");
    }
}
