//! The fixed train/validation/test split of every trace by scene, and the only doors through which
//! fitting and tuning ([`TuningSet`]) and the Table 4 evaluation ([`EvaluationSet`]) get traces.
//!
//! EyeNavGS (10 scenes, 22 sessions each; split by scene, never by time within a session, as the
//! dataset README and TileSplat App. C ask): 7 scenes train (154 sessions, 70%), 1 validation,
//! 2 test. 15% of 10 scenes is not a whole scene, so validation gets 10% and test 20% (test is the
//! larger so the evaluation has more sessions, one street capture and one object capture):
//! - train: alameda, bicycle, playroom, room, stump, train, treehill
//! - val: berlin
//! - test: nyc, truck
//!
//! Synthetic traces (generated walks and flights) are split by generator seed: `seed % 20` in
//! 0..14 train, 14..17 val, 17..20 test (exactly 70/15/15 over any 20 consecutive seeds).
//! A trace says its split in its `split` header and its EyeNavGS origin in `source`.

use super::eyenav::{Placement, SCENES, read_session, session_files};
use super::trace::Trace;

/// Which part of the data a trace belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Split {
    /// Predictors may learn from it.
    Train,
    /// Hyper-parameters may be chosen on it.
    Val,
    /// Only evaluated on, never fitted or tuned on.
    Test,
}

impl Split {
    /// The `split` header value.
    pub fn name(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Val => "val",
            Split::Test => "test",
        }
    }

    /// Parses a `split` header value.
    pub fn parse(s: &str) -> Option<Split> {
        match s {
            "train" => Some(Split::Train),
            "val" => Some(Split::Val),
            "test" => Some(Split::Test),
            _ => None,
        }
    }
}

/// The EyeNavGS scene assignment (see the module docs).
pub const EYENAV_SPLIT: [(&str, Split); 10] = [
    ("alameda", Split::Train),
    ("berlin", Split::Val),
    ("bicycle", Split::Train),
    ("nyc", Split::Test),
    ("playroom", Split::Train),
    ("room", Split::Train),
    ("stump", Split::Train),
    ("train", Split::Train),
    ("treehill", Split::Train),
    ("truck", Split::Test),
];

/// The split of an EyeNavGS scene.
pub fn eyenav_split(scene: &str) -> Option<Split> {
    EYENAV_SPLIT
        .iter()
        .find(|(s, _)| *s == scene)
        .map(|(_, sp)| *sp)
}

/// EyeNavGS scenes of one split, in [`SCENES`] order.
pub fn eyenav_scenes(split: Split) -> Vec<&'static str> {
    SCENES
        .iter()
        .copied()
        .filter(|s| eyenav_split(s) == Some(split))
        .collect()
}

/// The split of a synthetic trace generated with `seed`.
pub fn synthetic_split(seed: u64) -> Split {
    match seed % 20 {
        0..14 => Split::Train,
        14..17 => Split::Val,
        _ => Split::Test,
    }
}

/// The EyeNavGS scene a trace came from (its `source` header, `EyeNavGS SCENE/FILE`).
pub fn eyenav_scene_of(t: &Trace) -> Option<&str> {
    let src = t.header("source")?.strip_prefix("EyeNavGS ")?;
    src.split('/').next()
}

/// The split a trace belongs to, checked: an EyeNavGS trace's `split` header must match its scene's
/// split, a synthetic trace's must match its seed's. Errors say why.
pub fn split_of(t: &Trace) -> Result<Split, String> {
    let declared = t
        .header("split")
        .and_then(Split::parse)
        .ok_or("trace without a train/val/test split header")?;
    let truth = match eyenav_scene_of(t) {
        Some(scene) => {
            eyenav_split(scene).ok_or_else(|| format!("unknown EyeNavGS scene '{scene}'"))?
        }
        None => {
            let seed: u64 = t
                .header("seed")
                .and_then(|s| s.parse().ok())
                .ok_or("synthetic trace without a seed header")?;
            synthetic_split(seed)
        }
    };
    if truth != declared {
        return Err(format!(
            "trace says split '{}' but belongs to '{}'",
            declared.name(),
            truth.name()
        ));
    }
    Ok(truth)
}

/// Traces anything may be fitted (train) or tuned (val) on; never holds a test trace. Build it
/// only with [`TuningSet::admit`] or [`TuningSet::load_eyenav`].
#[derive(Debug, Clone, Default)]
pub struct TuningSet {
    train: Vec<Trace>,
    val: Vec<Trace>,
}

impl TuningSet {
    /// An empty set.
    pub fn new() -> Self {
        TuningSet::default()
    }

    /// Adds a train or val trace; a test trace (or one whose split header lies) is refused.
    pub fn admit(&mut self, t: Trace) -> Result<(), String> {
        match split_of(&t)? {
            Split::Train => self.train.push(t),
            Split::Val => self.val.push(t),
            Split::Test => return Err("a test trace may not be used for fitting or tuning".into()),
        }
        Ok(())
    }

    /// Every EyeNavGS session of the train and val scenes under `root`, placed by `placement`
    /// into `scene` (the test scenes' files are not even opened).
    pub fn load_eyenav(
        root: &std::path::Path,
        placement: &Placement,
        scene: &str,
    ) -> Result<TuningSet, String> {
        let mut set = TuningSet::new();
        for split in [Split::Train, Split::Val] {
            for s in eyenav_scenes(split) {
                for f in session_files(root, s)? {
                    set.admit(read_session(&f)?.place(placement, scene, split.name()))?;
                }
            }
        }
        Ok(set)
    }

    /// Training traces.
    pub fn train(&self) -> &[Trace] {
        &self.train
    }

    /// Validation traces.
    pub fn val(&self) -> &[Trace] {
        &self.val
    }
}

/// Traces the Table 4 evaluation runs on: test traces only.
#[derive(Debug, Clone, Default)]
pub struct EvaluationSet {
    test: Vec<Trace>,
}

impl EvaluationSet {
    /// An empty set.
    pub fn new() -> Self {
        EvaluationSet::default()
    }

    /// Adds a test trace; anything else is refused.
    pub fn admit(&mut self, t: Trace) -> Result<(), String> {
        match split_of(&t)? {
            Split::Test => {
                self.test.push(t);
                Ok(())
            }
            s => Err(format!(
                "a {} trace may not be used in the evaluation",
                s.name()
            )),
        }
    }

    /// Every EyeNavGS session of the test scenes under `root`, placed by `placement` into `scene`.
    pub fn load_eyenav(
        root: &std::path::Path,
        placement: &Placement,
        scene: &str,
    ) -> Result<EvaluationSet, String> {
        let mut set = EvaluationSet::new();
        for s in eyenav_scenes(Split::Test) {
            for f in session_files(root, s)? {
                set.admit(read_session(&f)?.place(placement, scene, "test"))?;
            }
        }
        Ok(set)
    }

    /// The test traces.
    pub fn traces(&self) -> &[Trace] {
        &self.test
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::ViewPose;
    use glam::DVec3;

    fn trace(headers: &[(&str, &str)]) -> Trace {
        Trace {
            headers: headers
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
            poses: vec![ViewPose {
                t: 0.0,
                pos: DVec3::ZERO,
                yaw: 0.0,
                pitch: 0.0,
            }],
        }
    }

    #[test]
    fn the_split_is_by_scene_and_covers_every_scene_once() {
        let n = |s| eyenav_scenes(s).len();
        assert_eq!((n(Split::Train), n(Split::Val), n(Split::Test)), (7, 1, 2));
        for s in SCENES {
            assert!(eyenav_split(s).is_some(), "{s}");
        }
        let counts = (0..20u64).fold([0; 3], |mut c, s| {
            c[synthetic_split(s) as usize] += 1;
            c
        });
        assert_eq!(counts, [14, 3, 3]);
    }

    #[test]
    fn test_traces_cannot_enter_tuning_and_train_traces_cannot_enter_evaluation() {
        let nyc = trace(&[
            ("source", "EyeNavGS nyc/user101_nyc.csv"),
            ("split", "test"),
        ]);
        let lie = trace(&[
            ("source", "EyeNavGS nyc/user101_nyc.csv"),
            ("split", "train"),
        ]);
        let alameda = trace(&[
            ("source", "EyeNavGS alameda/u_alameda.csv"),
            ("split", "train"),
        ]);
        let syn_test = trace(&[("seed", "19"), ("split", "test")]);
        let syn_lie = trace(&[("seed", "19"), ("split", "val")]);
        let syn_val = trace(&[("seed", "15"), ("split", "val")]);
        let none = trace(&[("seed", "1")]);
        let mut tune = TuningSet::new();
        assert!(tune.admit(nyc.clone()).is_err());
        assert!(
            tune.admit(lie.clone())
                .unwrap_err()
                .contains("belongs to 'test'")
        );
        assert!(tune.admit(syn_test.clone()).is_err());
        assert!(tune.admit(syn_lie.clone()).is_err());
        assert!(tune.admit(none.clone()).is_err());
        tune.admit(alameda.clone()).unwrap();
        tune.admit(syn_val.clone()).unwrap();
        assert_eq!((tune.train().len(), tune.val().len()), (1, 1));
        let mut eval = EvaluationSet::new();
        assert!(eval.admit(alameda).is_err());
        assert!(eval.admit(syn_val).is_err());
        assert!(eval.admit(lie).is_err());
        eval.admit(nyc).unwrap();
        eval.admit(syn_test).unwrap();
        assert_eq!(eval.traces().len(), 2);
    }

    /// With the shared traces (`data/navigation-traces/README.md`): the tuning set holds
    /// exactly the 8 train/val scenes' 176 sessions and no test scene; the evaluation set the 44
    /// sessions of nyc and truck.
    #[test]
    fn shared_sets_hold_the_right_scenes() {
        let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
            .join("data/navigation-traces");
        if !root.exists() {
            eprintln!("skipped: {} missing", root.display());
            return;
        }
        let pl = Placement::default();
        let tune = TuningSet::load_eyenav(&root, &pl, "x").unwrap();
        assert_eq!(tune.train().len() + tune.val().len(), 176);
        for t in tune.train().iter().chain(tune.val()) {
            let s = eyenav_scene_of(t).unwrap();
            assert_ne!(eyenav_split(s), Some(Split::Test), "{s}");
        }
        let eval = EvaluationSet::load_eyenav(&root, &pl, "x").unwrap();
        assert_eq!(eval.traces().len(), 44);
        for t in eval.traces() {
            let s = eyenav_scene_of(t).unwrap();
            assert!(s == "nyc" || s == "truck", "{s}");
        }
    }

    fn files(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        let Ok(rd) = std::fs::read_dir(dir) else {
            return;
        };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                files(&p, out);
            } else {
                out.push(p);
            }
        }
    }

    /// Nothing that fits or tunes can reach the EyeNavGS files but through this module: in the
    /// crates' and the binary's sources only the reader, this module and the streaming city
    /// (which hands its traces out through [`TuningSet`] and [`EvaluationSet`]) open sessions,
    /// and no fitting tool in `tools/` (`tools/tcn/train.py` reads exported train/val windows)
    /// or example mentions the traces at all.
    #[test]
    fn only_the_split_api_opens_the_human_traces() {
        let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
        let mut all = vec![];
        files(&root.join("src"), &mut all);
        for c in std::fs::read_dir(root.join("crates"))
            .into_iter()
            .flatten()
            .flatten()
        {
            files(&c.path().join("src"), &mut all);
        }
        // The learned predictor's export and evaluation (the lab's examples/tcn_*.rs) take the
        // traces' folder as an argument and go through stream_city's split sets too.
        files(&root.join("crates/lab/examples"), &mut all);
        files(&root.join("tools"), &mut all);
        let allowed = [
            "crates/stream/src/eyenav.rs",
            "crates/stream/src/split.rs",
            "crates/lab/src/sim/stream_city.rs",
            "crates/lab/src/sim/stream_city_tests.rs",
        ];
        let mut checked = 0;
        for f in all {
            let rel = f
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            let Ok(text) = std::fs::read_to_string(&f) else {
                continue;
            };
            checked += 1;
            if allowed.contains(&rel.as_str()) {
                continue;
            }
            for needle in ["read_session(", "session_files(", "navigation-traces"] {
                assert!(
                    !text.contains(needle),
                    "{rel} mentions '{needle}': go through sim::split"
                );
            }
            // The dataset's name may appear in comments and help text (the simulate tool reads
            // a file in its format that the user names); code naming it opens it some other way.
            let code = text
                .lines()
                .filter(|l| !l.trim_start().starts_with("//"))
                .any(|l| l.contains("EyeNavGS"));
            assert!(
                !code,
                "{rel} names 'EyeNavGS' in code: go through sim::split"
            );
        }
        assert!(checked > 50, "{checked} files checked");
    }
}
