//! Splat tiles from glb: reads any conforming `KHR_gaussian_splatting` glb (ours or another
//! writer's: any stride and offset, every component type the extension allows) back into `Splats`.

use glam::{DMat4, DQuat, DVec3};

use super::glb::{GlbError, parse_json, read_glb};
use super::gltf::{
    AccessorType, BufferView, ComponentType, Gltf, KHR_GAUSSIAN_SPLATTING,
    KHR_GAUSSIAN_SPLATTING_SPZ_2, KHR_MESH_QUANTIZATION, KhrGaussianSplatting, MODE_DEFAULT,
    MODE_POINTS, Node, Primitive,
};
use super::tile::{
    ATTR_COLOR_0, ATTR_OPACITY, ATTR_POSITION, ATTR_ROTATION, ATTR_SCALE, COLOR_SPACE_LINEAR,
    COLOR_SPACE_SRGB, KERNEL_ELLIPSE, sh_attribute,
};
use splat2tiles_core::splat::sh::color_to_sh0;
use splat2tiles_core::splat::{Splats, normalize_quat, sh_rest_count};

/// A tile decoded from a glb.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedTile {
    /// The splats; positions are the `POSITION` values (tile-relative, before the node matrix).
    pub splats: Splats,
    /// World matrix of the splat primitive's node, column-major (identity when absent).
    pub node_matrix: [f64; 16],
    /// `colorSpace` of the extension (`srgb_rec709_display` when the file omits it).
    pub color_space: String,
    /// `kernel` of the extension (`ellipse` when the file omits it).
    pub kernel: String,
    /// `asset.generator`, if any.
    pub generator: Option<String>,
    /// Whether the primitive carries `COLOR_0`.
    pub has_color0: bool,
    /// Tolerated departures from the spec (fallbacks used, values clamped or normalised).
    pub warnings: Vec<String>,
}

/// Which component types an attribute accepts (KHR_gaussian_splatting "Attributes" table).
#[derive(Clone, Copy)]
enum Allowed {
    /// Float only (SH, POSITION without KHR_mesh_quantization).
    Float,
    /// Float or any 8/16-bit integer, normalized or not (POSITION with KHR_mesh_quantization).
    Quantized,
    /// Float, signed byte/short normalized.
    Rotation,
    /// Float, (un)signed byte/short, normalized or not. The ratified text lists unsigned types,
    /// an earlier draft signed ones: both are read.
    Scale,
    /// Float, unsigned byte/short normalized (OPACITY, COLOR_0).
    Unorm,
}

impl Allowed {
    fn accepts(self, ct: ComponentType, normalized: bool) -> bool {
        use ComponentType::*;
        match (self, ct) {
            (_, F32) => !normalized,
            (_, U32) => false,
            (Allowed::Float, _) => false,
            (Allowed::Quantized | Allowed::Scale, _) => true,
            (Allowed::Rotation, I8 | I16) => normalized,
            (Allowed::Unorm, U8 | U16) => normalized,
            _ => false,
        }
    }
}

fn decode_component(ct: ComponentType, normalized: bool, b: &[u8]) -> f32 {
    match ct {
        ComponentType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        ComponentType::I8 => {
            let v = b[0] as i8 as f32;
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        ComponentType::U8 => {
            let v = b[0] as f32;
            if normalized { v / 255.0 } else { v }
        }
        ComponentType::I16 => {
            let v = i16::from_le_bytes([b[0], b[1]]) as f32;
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U16 => {
            let v = u16::from_le_bytes([b[0], b[1]]) as f32;
            if normalized { v / 65535.0 } else { v }
        }
        ComponentType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
    }
}

/// The decoding context: document, binary chunk and where the primitive sits.
struct Ctx<'a> {
    doc: &'a Gltf,
    bin: Option<&'a [u8]>,
    prim_path: String,
}

impl Ctx<'_> {
    /// Decodes accessor `index` (named by `semantic`) into `count * comps` floats.
    fn accessor(
        &self,
        semantic: &str,
        index: u32,
        kinds: &[AccessorType],
        allowed: Allowed,
        expect_count: Option<usize>,
    ) -> Result<(Vec<f32>, usize), GlbError> {
        let apath = format!("/accessors/{index}");
        let acc = self.doc.accessors.get(index as usize).ok_or_else(|| {
            GlbError::invalid(
                format!("{}/attributes/{semantic}", self.prim_path),
                format!("accessor {index} does not exist"),
            )
        })?;
        if !kinds.contains(&acc.kind) {
            return Err(GlbError::invalid(
                format!("{apath}/type"),
                format!("{semantic} must be {kinds:?}, found {:?}", acc.kind),
            ));
        }
        let ct = ComponentType::from_code(acc.component_type)
            .filter(|ct| allowed.accepts(*ct, acc.normalized))
            .ok_or_else(|| {
                GlbError::invalid(
                    format!("{apath}/componentType"),
                    format!(
                        "{semantic}: componentType {} (normalized {}) is not allowed",
                        acc.component_type, acc.normalized
                    ),
                )
            })?;
        if acc.sparse.is_some() {
            return Err(GlbError::unsupported(
                format!("{apath}/sparse"),
                "sparse accessors",
            ));
        }
        let count = usize::try_from(acc.count)
            .ok()
            .filter(|&c| c > 0)
            .ok_or_else(|| GlbError::invalid(format!("{apath}/count"), "count must be >= 1"))?;
        if let Some(want) = expect_count
            && count != want
        {
            return Err(GlbError::invalid(
                format!("{apath}/count"),
                format!("{semantic} has {count} elements, POSITION has {want}"),
            ));
        }
        let comps = acc.kind.components();
        let elem = comps * ct.size();
        let Some(view_index) = acc.buffer_view else {
            // glTF: an accessor without bufferView reads as zeros. Only allowed once POSITION
            // (which must have data) has bounded the count, so this cannot allocate without limit.
            if expect_count.is_none() {
                return Err(GlbError::unsupported(
                    format!("{apath}/bufferView"),
                    "POSITION without a bufferView (data held by an extension)",
                ));
            }
            return Ok((vec![0.0; count * comps], comps));
        };
        let vpath = format!("/bufferViews/{view_index}");
        let view = self
            .doc
            .buffer_views
            .get(view_index as usize)
            .ok_or_else(|| {
                GlbError::invalid(
                    format!("{apath}/bufferView"),
                    format!("bufferView {view_index} does not exist"),
                )
            })?;
        let data = self.view_bytes(view, &vpath)?;
        let stride = match view.byte_stride {
            None => elem,
            Some(s) if (s as usize) >= elem => s as usize,
            Some(s) => {
                return Err(GlbError::invalid(
                    format!("{vpath}/byteStride"),
                    format!("byteStride {s} is less than the element size {elem}"),
                ));
            }
        };
        let needed = (count as u64 - 1)
            .checked_mul(stride as u64)
            .and_then(|v| v.checked_add(elem as u64))
            .and_then(|v| v.checked_add(acc.byte_offset));
        if needed.is_none_or(|n| n > data.len() as u64) {
            return Err(GlbError::invalid(
                apath,
                format!(
                    "byteOffset {} + {count} elements of {elem} bytes (stride {stride}) run past \
                     the end of bufferView {view_index} ({} bytes)",
                    acc.byte_offset,
                    data.len()
                ),
            ));
        }
        let data = &data[acc.byte_offset as usize..];
        let cs = ct.size();
        let mut out = Vec::with_capacity(count * comps);
        if ct == ComponentType::F32 {
            // Floats (every Best tile, packed or interleaved): element by element, without the
            // per-component dispatch. `needed` above bounds the last element.
            out.resize(count * comps, 0.0);
            for (o, e) in out.chunks_exact_mut(comps).zip(data.chunks(stride)) {
                for (v, b) in o.iter_mut().zip(e[..elem].chunks_exact(4)) {
                    *v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
            }
            return Ok((out, comps));
        }
        for i in 0..count {
            let e = &data[i * stride..i * stride + elem];
            for c in 0..comps {
                out.push(decode_component(
                    ct,
                    acc.normalized,
                    &e[c * cs..(c + 1) * cs],
                ));
            }
        }
        Ok((out, comps))
    }

    /// The bytes of a bufferView, checked against its buffer and the BIN chunk.
    fn view_bytes(&self, view: &BufferView, vpath: &str) -> Result<&[u8], GlbError> {
        let bpath = format!("/buffers/{}", view.buffer);
        let buffer = self.doc.buffers.get(view.buffer as usize).ok_or_else(|| {
            GlbError::invalid(
                format!("{vpath}/buffer"),
                format!("buffer {} does not exist", view.buffer),
            )
        })?;
        if view.buffer != 0 || buffer.uri.is_some() {
            return Err(GlbError::unsupported(
                bpath,
                "buffers other than the glb BIN chunk (external or data URIs)",
            ));
        }
        let bin = self
            .bin
            .ok_or_else(|| GlbError::invalid(&bpath, "the glb has no BIN chunk"))?;
        if buffer.byte_length > bin.len() as u64 {
            return Err(GlbError::invalid(
                format!("{bpath}/byteLength"),
                format!(
                    "byteLength {} exceeds the BIN chunk ({} bytes)",
                    buffer.byte_length,
                    bin.len()
                ),
            ));
        }
        let end = view.byte_offset.checked_add(view.byte_length);
        if end.is_none_or(|e| e > buffer.byte_length) {
            return Err(GlbError::invalid(
                vpath,
                format!(
                    "byteOffset {} + byteLength {} run past the end of buffer {} ({} bytes)",
                    view.byte_offset, view.byte_length, view.buffer, buffer.byte_length
                ),
            ));
        }
        Ok(&bin[view.byte_offset as usize..(view.byte_offset + view.byte_length) as usize])
    }
}

/// Local transform of a node (matrix, or T * R * S), column-major.
fn local_matrix(node: &Node) -> DMat4 {
    if let Some(m) = node.matrix {
        return DMat4::from_cols_array(&m);
    }
    let t = node.translation.map_or(DVec3::ZERO, DVec3::from_array);
    let s = node.scale.map_or(DVec3::ONE, DVec3::from_array);
    let r = node
        .rotation
        .map(DQuat::from_array)
        .filter(|q| q.length_squared() > 0.0)
        .map_or(DQuat::IDENTITY, |q| q.normalize());
    DMat4::from_scale_rotation_translation(s, r, t)
}

/// Every (mesh index, world matrix) placed by the default scene (or scene 0).
fn placed_meshes(doc: &Gltf) -> Result<Vec<(usize, DMat4, String)>, GlbError> {
    let roots: Vec<u32> =
        match doc
            .scene
            .map(|s| s as usize)
            .or(if doc.scenes.is_empty() { None } else { Some(0) })
        {
            Some(s) => doc
                .scenes
                .get(s)
                .ok_or_else(|| GlbError::invalid("/scene", format!("scene {s} does not exist")))?
                .nodes
                .clone(),
            // No scene: every node that is nobody's child is a root.
            None => {
                let mut is_child = vec![false; doc.nodes.len()];
                for n in &doc.nodes {
                    for &c in &n.children {
                        if let Some(f) = is_child.get_mut(c as usize) {
                            *f = true;
                        }
                    }
                }
                (0..doc.nodes.len() as u32)
                    .filter(|&i| !is_child[i as usize])
                    .collect()
            }
        };
    let mut visited = vec![false; doc.nodes.len()];
    let mut stack: Vec<(u32, DMat4)> = roots.iter().rev().map(|&r| (r, DMat4::IDENTITY)).collect();
    let mut out = Vec::new();
    while let Some((i, parent)) = stack.pop() {
        let path = format!("/nodes/{i}");
        let node = doc
            .nodes
            .get(i as usize)
            .ok_or_else(|| GlbError::invalid(&path, "node does not exist"))?;
        if std::mem::replace(&mut visited[i as usize], true) {
            return Err(GlbError::invalid(
                path,
                "node reached twice (a cycle or a shared child)",
            ));
        }
        let world = parent * local_matrix(node);
        if let Some(m) = node.mesh {
            if m as usize >= doc.meshes.len() {
                return Err(GlbError::invalid(
                    format!("{path}/mesh"),
                    format!("mesh {m} does not exist"),
                ));
            }
            out.push((m as usize, world, path));
        }
        for &c in node.children.iter().rev() {
            stack.push((c, world));
        }
    }
    Ok(out)
}

/// sRGB encoding (linear -> display), the inverse of [`srgb_to_linear`].
fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The one splat primitive the default scene places, checked for what this reader decodes.
struct SplatPrimitive<'a> {
    prim: &'a Primitive,
    ext: &'a KhrGaussianSplatting,
    world: DMat4,
    path: String,
}

/// Finds the scene's one splat primitive: POINTS, unindexed, with no child extension.
fn find_splat_primitive(doc: &Gltf) -> Result<SplatPrimitive<'_>, GlbError> {
    let mut found = Vec::new();
    for (m, world, node_path) in placed_meshes(doc)? {
        for (p, prim) in doc.meshes[m].primitives.iter().enumerate() {
            let ext = prim
                .extensions
                .as_ref()
                .and_then(|e| e.gaussian_splatting.as_ref());
            if let Some(ext) = ext {
                found.push((m, p, prim, ext, world, node_path.clone()));
            }
        }
    }
    if found.is_empty() {
        return Err(GlbError::invalid(
            "/meshes",
            "no primitive placed by the scene has the KHR_gaussian_splatting extension",
        ));
    }
    if found.len() > 1 {
        return Err(GlbError::unsupported(
            found[1].5.clone(),
            format!(
                "{} placed splat primitives (this reader decodes one per tile)",
                found.len()
            ),
        ));
    }
    let (m, p, prim, ext, world, _) = found.swap_remove(0);
    let path = format!("/meshes/{m}/primitives/{p}");
    let mode = prim.mode.unwrap_or(MODE_DEFAULT);
    if mode != MODE_POINTS {
        return Err(GlbError::invalid(
            format!("{path}/mode"),
            format!("mode {mode}: KHR_gaussian_splatting primitives must be POINTS (0)"),
        ));
    }
    if prim.indices.is_some() {
        return Err(GlbError::unsupported(
            format!("{path}/indices"),
            "indexed splat primitives",
        ));
    }
    if let Some(children) = &ext.extensions
        && let Some(name) = children.keys().next()
    {
        let what = if name == KHR_GAUSSIAN_SPLATTING_SPZ_2 {
            "SPZ-compressed splats (decode with the SPZ reader)".to_string()
        } else {
            format!("child extension {name}")
        };
        return Err(GlbError::unsupported(
            format!("{path}/extensions/{KHR_GAUSSIAN_SPLATTING}/extensions/{name}"),
            what,
        ));
    }
    Ok(SplatPrimitive {
        prim,
        ext,
        world,
        path,
    })
}

/// The primitive's attributes decoded, before tidying.
struct RawAttributes {
    pos: Vec<f32>,
    rot: Vec<f32>,
    scale: Vec<f32>,
    opacity: Vec<f32>,
    sh0: Vec<[f32; 3]>,
    has_color0: bool,
}

impl Ctx<'_> {
    /// Accessor index of attribute `name`, if the primitive has it.
    fn attr(&self, prim: &Primitive, name: &str) -> Option<u32> {
        prim.attributes.get(name).copied()
    }

    /// Accessor index of attribute `name`, an error when the primitive lacks it.
    fn required(&self, prim: &Primitive, name: &str) -> Result<u32, GlbError> {
        self.attr(prim, name).ok_or_else(|| {
            GlbError::invalid(
                format!("{}/attributes", self.prim_path),
                format!("missing required attribute {name}"),
            )
        })
    }

    /// Decodes position, rotation, scale, opacity and SH degree 0 (the last two may come from
    /// `COLOR_0`).
    fn raw_attributes(
        &self,
        prim: &Primitive,
        color_space: &str,
        warnings: &mut Vec<String>,
    ) -> Result<RawAttributes, GlbError> {
        use AccessorType::{Scalar, Vec3, Vec4};
        let quantized = self
            .doc
            .extensions_used
            .iter()
            .any(|e| e == KHR_MESH_QUANTIZATION);
        let pos_allowed = if quantized {
            Allowed::Quantized
        } else {
            Allowed::Float
        };
        let index = self.required(prim, ATTR_POSITION)?;
        let (pos, _) = self.accessor(ATTR_POSITION, index, &[Vec3], pos_allowed, None)?;
        let n = pos.len() / 3;
        let index = self.required(prim, ATTR_ROTATION)?;
        let (rot, _) = self.accessor(ATTR_ROTATION, index, &[Vec4], Allowed::Rotation, Some(n))?;
        let index = self.required(prim, ATTR_SCALE)?;
        let (scale, _) = self.accessor(ATTR_SCALE, index, &[Vec3], Allowed::Scale, Some(n))?;
        let color = self
            .attr(prim, ATTR_COLOR_0)
            .map(|i| self.accessor(ATTR_COLOR_0, i, &[Vec3, Vec4], Allowed::Unorm, Some(n)))
            .transpose()?;
        let opacity = match self.attr(prim, ATTR_OPACITY) {
            Some(i) => {
                self.accessor(ATTR_OPACITY, i, &[Scalar], Allowed::Unorm, Some(n))?
                    .0
            }
            None => match &color {
                Some((c, 4)) => {
                    warnings.push("OPACITY missing; taken from COLOR_0 alpha".into());
                    c.chunks_exact(4).map(|c| c[3]).collect()
                }
                _ => {
                    return Err(GlbError::invalid(
                        format!("{}/attributes", self.prim_path),
                        format!("missing required attribute {ATTR_OPACITY} (and no COLOR_0 alpha)"),
                    ));
                }
            },
        };
        let sh0_name = sh_attribute(0, 0);
        let sh0: Vec<[f32; 3]> = match self.attr(prim, &sh0_name) {
            Some(i) => {
                let (v, _) = self.accessor(&sh0_name, i, &[Vec3], Allowed::Float, Some(n))?;
                v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            }
            None => match &color {
                Some((c, comps)) => {
                    warnings.push(format!("{sh0_name} missing; derived from COLOR_0"));
                    let srgb = color_space != COLOR_SPACE_LINEAR;
                    c.chunks_exact(*comps)
                        .map(|c| {
                            let rgb = [c[0], c[1], c[2]];
                            color_to_sh0(if srgb { rgb.map(linear_to_srgb) } else { rgb })
                        })
                        .collect()
                }
                None => {
                    return Err(GlbError::invalid(
                        format!("{}/attributes", self.prim_path),
                        format!("missing {sh0_name} and no COLOR_0 to fall back on"),
                    ));
                }
            },
        };
        Ok(RawAttributes {
            pos,
            rot,
            scale,
            opacity,
            sh0,
            has_color0: color.is_some(),
        })
    }

    /// The SH degree (the highest whose coefficients, and all lower ones, are all present) and
    /// its rest coefficients for `n` splats.
    fn sh_rest(
        &self,
        prim: &Primitive,
        n: usize,
        warnings: &mut Vec<String>,
    ) -> Result<(u8, Vec<[f32; 3]>), GlbError> {
        let mut degree = 0u8;
        for l in 1..=3u8 {
            let present = (0..=2 * l)
                .filter(|&c| self.attr(prim, &sh_attribute(l, c)).is_some())
                .count();
            if present == 0 {
                break;
            }
            if present as u8 != 2 * l + 1 || degree != l - 1 {
                warnings.push(format!(
                    "SH degree {l} has {present} of {} coefficients; degrees from {l} up ignored",
                    2 * l + 1
                ));
                break;
            }
            degree = l;
        }
        let k = sh_rest_count(degree);
        let mut sh_rest = vec![[0f32; 3]; n * k];
        for l in 1..=degree {
            for c in 0..=2 * l {
                let name = sh_attribute(l, c);
                let index = self.required(prim, &name)?;
                let (v, _) =
                    self.accessor(&name, index, &[AccessorType::Vec3], Allowed::Float, Some(n))?;
                let j = (l as usize).pow(2) - 1 + c as usize;
                for (i, t) in v.chunks_exact(3).enumerate() {
                    sh_rest[i * k + j] = [t[0], t[1], t[2]];
                }
            }
        }
        Ok((degree, sh_rest))
    }
}

/// Normalises rotations that are not unit (quantised ones), keeping float unit ones bit-exact.
fn unit_rotations(rot: &[f32], warnings: &mut Vec<String>) -> Vec<[f32; 4]> {
    let mut renormalised = 0usize;
    let rotations: Vec<[f32; 4]> = rot
        .chunks_exact(4)
        .map(|q| {
            let q = [q[0], q[1], q[2], q[3]];
            let n2: f64 = q.iter().map(|&v| v as f64 * v as f64).sum();
            if (n2.sqrt() - 1.0).abs() > 1e-4 {
                renormalised += 1;
                normalize_quat(q)
            } else {
                q
            }
        })
        .collect();
    if renormalised > 0 {
        warnings.push(format!(
            "{renormalised} rotations were not unit quaternions; normalised"
        ));
    }
    rotations
}

/// Clamps opacities outside [0, 1] (NaN kept for the caller's checks).
fn clamped_opacities(opacity: Vec<f32>, warnings: &mut Vec<String>) -> Vec<f32> {
    let mut clamped = 0usize;
    let opacities: Vec<f32> = opacity
        .into_iter()
        .map(|a| {
            if (0.0..=1.0).contains(&a) || a.is_nan() {
                a
            } else {
                clamped += 1;
                a.clamp(0.0, 1.0)
            }
        })
        .collect();
    if clamped > 0 {
        warnings.push(format!("{clamped} opacities outside [0, 1]; clamped"));
    }
    opacities
}

/// Reads a `KHR_gaussian_splatting` glb: ours or any other conforming writer's (any stride and
/// offset, every component type the extension allows, optional SH degrees and `COLOR_0`).
///
/// The one splat primitive placed by the default scene is decoded; its node's world matrix is
/// returned as `node_matrix`. Allocations stay proportional to the input size.
pub fn read_tile_glb(bytes: &[u8]) -> Result<DecodedTile, GlbError> {
    let chunks = read_glb(bytes)?;
    let doc = parse_json(&chunks)?;
    for (i, ext) in doc.extensions_required.iter().enumerate() {
        if ext != KHR_GAUSSIAN_SPLATTING && ext != KHR_MESH_QUANTIZATION {
            return Err(GlbError::unsupported(
                format!("/extensionsRequired/{i}"),
                format!("required extension {ext}"),
            ));
        }
    }
    let mut warnings = Vec::new();
    let SplatPrimitive {
        prim,
        ext,
        world,
        path: prim_path,
    } = find_splat_primitive(&doc)?;
    let kernel = ext.kernel.clone().unwrap_or_else(|| {
        warnings.push("kernel missing; read as ellipse".into());
        KERNEL_ELLIPSE.into()
    });
    let color_space = ext.color_space.clone().unwrap_or_else(|| {
        warnings.push("colorSpace missing; read as srgb_rec709_display".into());
        COLOR_SPACE_SRGB.into()
    });
    let ctx = Ctx {
        doc: &doc,
        bin: chunks.bin,
        prim_path,
    };
    let raw = ctx.raw_attributes(prim, &color_space, &mut warnings)?;
    let n = raw.pos.len() / 3;
    let (degree, sh_rest) = ctx.sh_rest(prim, n, &mut warnings)?;
    let rotations = unit_rotations(&raw.rot, &mut warnings);
    let opacities = clamped_opacities(raw.opacity, &mut warnings);
    let negative = raw.scale.iter().filter(|&&s| s < 0.0).count();
    if negative > 0 {
        warnings.push(format!(
            "{negative} negative scale components (the spec wants linear, non-negative)"
        ));
    }
    let splats = Splats {
        positions: raw
            .pos
            .chunks_exact(3)
            .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64])
            .collect(),
        scales: raw
            .scale
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
        rotations,
        opacities,
        sh0: raw.sh0,
        sh_degree: degree,
        sh_rest,
    };
    splats.check_lengths();
    Ok(DecodedTile {
        splats,
        node_matrix: world.to_cols_array(),
        color_space,
        kernel,
        generator: doc.asset.generator.clone(),
        has_color0: raw.has_color0,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::gltf::{Mesh, Scene};

    #[test]
    fn trs_nodes_and_hierarchy_compose() {
        let doc = Gltf {
            scenes: vec![Scene {
                nodes: vec![0],
                name: None,
            }],
            nodes: vec![
                Node {
                    children: vec![1],
                    translation: Some([1.0, 2.0, 3.0]),
                    ..Default::default()
                },
                Node {
                    mesh: Some(0),
                    scale: Some([2.0, 2.0, 2.0]),
                    ..Default::default()
                },
            ],
            meshes: vec![Mesh::default()],
            ..Default::default()
        };
        let placed = placed_meshes(&doc).unwrap();
        assert_eq!(placed.len(), 1);
        let m = placed[0].1.to_cols_array();
        assert_eq!(m[0], 2.0);
        assert_eq!(&m[12..15], &[1.0, 2.0, 3.0]);
    }

    #[test]
    fn quantized_components_decode() {
        assert_eq!(decode_component(ComponentType::I8, true, &[0x81]), -1.0);
        assert_eq!(decode_component(ComponentType::I8, true, &[0x80]), -1.0);
        assert_eq!(decode_component(ComponentType::U8, true, &[255]), 1.0);
        assert_eq!(
            decode_component(ComponentType::U16, true, &[0xff, 0xff]),
            1.0
        );
        assert_eq!(
            decode_component(ComponentType::I16, true, &32767i16.to_le_bytes()),
            1.0
        );
        assert_eq!(decode_component(ComponentType::U8, false, &[7]), 7.0);
        assert!(Allowed::Rotation.accepts(ComponentType::I8, true));
        assert!(!Allowed::Rotation.accepts(ComponentType::I8, false));
        assert!(!Allowed::Float.accepts(ComponentType::U8, true));
        assert!(Allowed::Scale.accepts(ComponentType::U16, false));
        assert!(!Allowed::Unorm.accepts(ComponentType::U8, false));
    }
}
