//! Trainer-layout PLY writer (binary little endian, 62 floats for SH degree 3): the inverse of
//! the reader's conversions (log scale, logit opacity, w,x,y,z quaternion, channel-major f_rest).

use std::io::{self, Write};

use splat2tiles_core::splat::{self, Splats};

/// Smallest scale written, so that `ln` stays finite (a zero scale reads back as about 1e-30).
const MIN_SCALE: f32 = 1e-30;
/// Splats encoded per `write_all`.
const CHUNK: usize = 4096;

/// Writes `splats` as a trainer PLY: properties `x y z nx ny nz f_dc_0..2 f_rest_* opacity
/// scale_0..2 rot_0..3`, all float, normals 0.
pub fn write_ply(splats: &Splats, w: impl Write) -> io::Result<()> {
    splats.check_lengths();
    let mut pw = PlyWriter::new(w, splats.len() as u64, splats.sh_degree)?;
    pw.write(splats)?;
    pw.finish()
}

/// A trainer PLY written in chunks: the header declares `count` splats up front, then
/// [`PlyWriter::write`] appends them (scenes larger than memory are streamed this way).
pub struct PlyWriter<W: Write> {
    w: W,
    degree: u8,
    declared: u64,
    written: u64,
    buf: Vec<u8>,
}

impl<W: Write> PlyWriter<W> {
    /// Writes the header for `count` splats of SH degree `degree`.
    pub fn new(mut w: W, count: u64, degree: u8) -> io::Result<Self> {
        let per = splat::sh_rest_count(degree);
        let mut h = String::new();
        h += "ply\nformat binary_little_endian 1.0\n";
        h += &format!("element vertex {count}\n");
        for n in [
            "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
        ] {
            h += &format!("property float {n}\n");
        }
        for k in 0..per * 3 {
            h += &format!("property float f_rest_{k}\n");
        }
        for n in [
            "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
        ] {
            h += &format!("property float {n}\n");
        }
        h += "end_header\n";
        w.write_all(h.as_bytes())?;
        Ok(PlyWriter {
            w,
            degree,
            declared: count,
            written: 0,
            buf: Vec::new(),
        })
    }

    /// Appends `splats` (same SH degree); more than the header declared is an error.
    pub fn write(&mut self, splats: &Splats) -> io::Result<()> {
        if splats.sh_degree != self.degree {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "SH degree {} written to a PLY declared with degree {}",
                    splats.sh_degree, self.degree
                ),
            ));
        }
        if self.written + splats.len() as u64 > self.declared {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("more than the {} splats the header declares", self.declared),
            ));
        }
        let per = splats.rest_per_splat();
        let floats = 17 + per * 3;
        for start in (0..splats.len()).step_by(CHUNK) {
            let buf = &mut self.buf;
            buf.clear();
            buf.reserve(CHUNK * floats * 4);
            for i in start..(start + CHUNK).min(splats.len()) {
                let mut put = |v: f32| buf.extend_from_slice(&v.to_le_bytes());
                let p = splats.positions[i];
                p.iter().for_each(|v| put(*v as f32));
                (0..3).for_each(|_| put(0.0));
                splats.sh0[i].iter().for_each(|v| put(*v));
                let rest = splats.rest_of(i);
                for c in 0..3 {
                    rest.iter().for_each(|t| put(t[c]));
                }
                put(splat::logit(splats.opacities[i]));
                splats.scales[i]
                    .iter()
                    .for_each(|s| put(s.max(MIN_SCALE).ln()));
                let [x, y, z, qw] = splats.rotations[i];
                [qw, x, y, z].iter().for_each(|v| put(*v));
            }
            self.w.write_all(&self.buf)?;
        }
        self.written += splats.len() as u64;
        Ok(())
    }

    /// Checks that every declared splat was written and flushes.
    pub fn finish(mut self) -> io::Result<()> {
        if self.written != self.declared {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "{} splats written, the header declares {}",
                    self.written, self.declared
                ),
            ));
        }
        self.w.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

    fn scene(n: usize) -> Splats {
        let mut s = Splats::new(1);
        for i in 0..n {
            let t = i as f32;
            s.push(
                Splat {
                    position: [t as f64, -t as f64, 0.5],
                    scale: [0.1, 0.2, 0.3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.5,
                    sh0: [t * 0.01, 0.0, -0.1],
                },
                &[[t, 0.0, 1.0], [0.5, t, 0.0], [0.0, 0.0, t]],
            );
        }
        s
    }

    #[test]
    fn chunked_writes_equal_one_write() {
        let s = scene(10);
        let mut whole = Vec::new();
        write_ply(&s, &mut whole).unwrap();
        let mut chunked = Vec::new();
        let mut w = PlyWriter::new(&mut chunked, 10, 1).unwrap();
        w.write(&s.select(&[0, 1, 2, 3])).unwrap();
        w.write(&s.select(&[4, 5, 6, 7, 8, 9])).unwrap();
        w.finish().unwrap();
        assert_eq!(whole, chunked);
        let back = crate::read_bytes("t.ply", &chunked).unwrap().splats;
        assert_eq!(back.len(), 10);
        assert_eq!(back.sh_rest, s.sh_rest);
    }

    #[test]
    fn counts_and_degrees_that_disagree_with_the_header_are_errors() {
        let s = scene(3);
        let mut out = Vec::new();
        let mut w = PlyWriter::new(&mut out, 2, 1).unwrap();
        assert!(w.write(&s).is_err(), "more splats than declared");
        assert!(w.write(&Splats::new(0)).is_err(), "another SH degree");
        w.write(&s.select(&[0])).unwrap();
        assert!(w.finish().is_err(), "fewer splats than declared");
    }
}
