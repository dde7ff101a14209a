//! Coordinate frames: the rotation from a scene file's own frame to the z-up tileset frame, and,
//! only for georeferenced scenes, WGS84 ENU/ECEF maths and Web-Mercator tile keys.

pub mod geo;
pub mod mercator;
pub mod region;

use glam::{DMat3, DMat4, DVec3};
use std::fmt;
use std::str::FromStr;

/// Which axis of the source file points up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpAxis {
    /// +x is up.
    PosX,
    /// -x is up.
    NegX,
    /// +y is up (glTF, SPZ's RUB frame).
    PosY,
    /// -y is up (COLMAP / INRIA trainer scenes).
    NegY,
    /// +z is up (3D Tiles, most GIS data).
    PosZ,
    /// -z is up.
    NegZ,
}

impl UpAxis {
    /// The up direction as a vector in the source frame.
    pub fn vector(self) -> DVec3 {
        match self {
            UpAxis::PosX => DVec3::X,
            UpAxis::NegX => -DVec3::X,
            UpAxis::PosY => DVec3::Y,
            UpAxis::NegY => -DVec3::Y,
            UpAxis::PosZ => DVec3::Z,
            UpAxis::NegZ => -DVec3::Z,
        }
    }

    /// The proper rotation taking this axis to +z (a quarter or half turn about x or y).
    pub fn to_z_up(self) -> DMat3 {
        use std::f64::consts::{FRAC_PI_2, PI};
        match self {
            UpAxis::PosZ => DMat3::IDENTITY,
            UpAxis::NegZ => DMat3::from_rotation_x(PI),
            UpAxis::PosY => DMat3::from_rotation_x(FRAC_PI_2),
            UpAxis::NegY => DMat3::from_rotation_x(-FRAC_PI_2),
            UpAxis::PosX => DMat3::from_rotation_y(-FRAC_PI_2),
            UpAxis::NegX => DMat3::from_rotation_y(FRAC_PI_2),
        }
    }
}

impl FromStr for UpAxis {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s.trim().to_ascii_lowercase().as_str() {
            "+x" | "x" => UpAxis::PosX,
            "-x" => UpAxis::NegX,
            "+y" | "y" => UpAxis::PosY,
            "-y" => UpAxis::NegY,
            "+z" | "z" => UpAxis::PosZ,
            "-z" => UpAxis::NegZ,
            other => {
                return Err(format!(
                    "unknown up axis '{other}' (use +x, -x, +y, -y, +z or -z)"
                ));
            }
        })
    }
}

impl fmt::Display for UpAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            UpAxis::PosX => "+x",
            UpAxis::NegX => "-x",
            UpAxis::PosY => "+y",
            UpAxis::NegY => "-y",
            UpAxis::PosZ => "+z",
            UpAxis::NegZ => "-z",
        })
    }
}

/// The glTF y-up to 3D Tiles z-up rotation (+90 deg about x) that clients apply to content.
pub fn y_up_to_z_up() -> DMat3 {
    DMat3::from_rotation_x(std::f64::consts::FRAC_PI_2)
}

/// The rotation A from the source frame S to the z-up tileset frame T: the up axis goes to +z,
/// then a turn of `heading_deg` about +z (counter-clockwise seen from above).
pub fn source_to_tileset(up: UpAxis, heading_deg: f64) -> DMat3 {
    DMat3::from_rotation_z(heading_deg.to_radians()) * up.to_z_up()
}

/// The glTF node matrix of a tile: maps tile-relative source coordinates (position minus the
/// tile centre `centre_s`, in S) into glTF's y-up frame, so that the client's y-up -> z-up step
/// lands them at their place in T. Column-major, as glTF stores it.
pub fn node_matrix(a: DMat3, centre_s: DVec3) -> [f64; 16] {
    let r = y_up_to_z_up().transpose() * a;
    let t = r * centre_s;
    DMat4::from_cols(
        r.x_axis.extend(0.0),
        r.y_axis.extend(0.0),
        r.z_axis.extend(0.0),
        t.extend(1.0),
    )
    .to_cols_array()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_up_axis_goes_to_z_and_is_proper() {
        for s in ["+x", "-x", "+y", "-y", "+z", "-z"] {
            let u: UpAxis = s.parse().unwrap();
            assert_eq!(u.to_string(), s);
            let m = u.to_z_up();
            let z = m * u.vector();
            assert!((z - DVec3::Z).length() < 1e-12, "{s} -> {z}");
            assert!((m.determinant() - 1.0).abs() < 1e-12, "{s} not a rotation");
        }
        assert!("up".parse::<UpAxis>().is_err());
    }

    #[test]
    fn node_matrix_lands_content_in_tileset_frame() {
        let a = source_to_tileset(UpAxis::NegY, 30.0);
        let c = DVec3::new(10.0, -2.0, 5.5);
        let m = DMat4::from_cols_array(&node_matrix(a, c));
        let p_rel = DVec3::new(0.25, 1.0, -3.0);
        let gltf = m.transform_point3(p_rel);
        let in_t = y_up_to_z_up() * gltf;
        let want = a * (p_rel + c);
        assert!((in_t - want).length() < 1e-12);
    }

    #[test]
    fn cesium_ion_node_matrix_for_z_up_data() {
        // z-up data at the origin gives the matrix Cesium ion writes.
        let m = node_matrix(DMat3::IDENTITY, DVec3::ZERO);
        let want = [
            1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        for (a, b) in m.iter().zip(want) {
            assert!((a - b).abs() < 1e-15, "{m:?}");
        }
    }
}
