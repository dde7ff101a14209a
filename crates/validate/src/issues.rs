//! The issue catalogue of `splat2tiles validate`: one constructor per code, each with a fixed
//! severity (codes reuse CesiumGS/3d-tiles-validator names where the meaning matches).

use serde::{Deserialize, Serialize};

/// How bad an issue is: ERROR fails validation, WARNING may mislead clients, INFO is a note.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum Severity {
    /// The input breaks a MUST of a specification.
    Error,
    /// Valid, but clients may misbehave.
    Warning,
    /// A note that does not affect validity.
    Info,
}

impl std::fmt::Display for Severity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Severity::Error => "ERROR",
            Severity::Warning => "WARNING",
            Severity::Info => "INFO",
        })
    }
}

/// One finding: a code, where it is (`file#/json/pointer` or `file@byte N`), and what is wrong.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Issue {
    /// UPPER_SNAKE code from [`CATALOGUE`].
    #[serde(rename = "type")]
    pub code: String,
    /// Location: a file relative to the tileset folder plus a JSON pointer or byte offset.
    pub path: String,
    /// What is wrong and, where possible, how to fix it.
    pub message: String,
    /// Fixed by the code.
    pub severity: Severity,
    /// The issues of a nested document (an external tileset) that this one summarises.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub causes: Vec<Issue>,
}

impl Issue {
    /// This issue with `causes` attached.
    pub fn with_causes(mut self, causes: Vec<Issue>) -> Issue {
        self.causes = causes;
        self
    }
}

macro_rules! catalogue {
    ($($(#[doc = $doc:literal])* $code:ident => $sev:ident,)*) => {
        /// Every issue code with its severity and a one-line meaning.
        pub const CATALOGUE: &[(&str, Severity, &str)] = &[
            $((stringify!($code), Severity::$sev, concat!($($doc),*)),)*
        ];

        #[allow(non_snake_case)]
        impl Issue {
            $(
                $(#[doc = $doc])*
                pub fn $code(path: impl Into<String>, message: impl Into<String>) -> Issue {
                    Issue {
                        code: stringify!($code).to_string(),
                        path: path.into(),
                        message: message.into(),
                        severity: Severity::$sev,
                        causes: Vec::new(),
                    }
                }
            )*
        }
    };
}

catalogue! {
    /// A file could not be read (missing, unreadable, or the path is not a file).
    IO_ERROR => Error,
    /// A relative URI climbs out of the tileset folder or is an absolute path.
    URI_OUTSIDE_TILESET => Error,
    /// A URI is not a usable relative reference (bad percent-encoding, NUL byte, empty path).
    URI_INVALID => Error,
    /// A URI names a remote resource (http, https, data...), not allowed without --allow-remote.
    URI_REMOTE => Error,
    /// A remote URI was allowed (--allow-remote) but was not fetched, so not validated.
    URI_REMOTE_NOT_VALIDATED => Warning,
    /// A gzip or zstd file decompresses beyond the size or ratio limit (compression bomb).
    DECOMPRESSION_LIMIT_EXCEEDED => Error,
    /// A JSON document (tileset, subtree or glTF chunk) does not parse.
    JSON_PARSE_ERROR => Error,
    /// A tileset JSON nests arrays/objects deeper than the validator follows (1024 levels).
    JSON_NESTING_TOO_DEEP => Error,
    /// A JSON document holds more values than the validator parses (4M: a few hundred MiB).
    JSON_TOO_LARGE => Error,
    /// An external tileset has errors (listed as causes).
    EXTERNAL_TILESET_VALIDATION_ERROR => Error,
    /// An external tileset has warnings but no errors (listed as causes).
    EXTERNAL_TILESET_VALIDATION_WARNING => Warning,
    /// An external tileset has only notes (listed as causes).
    EXTERNAL_TILESET_VALIDATION_INFO => Info,
    /// A tile content (glb, glTF, b3dm, i3dm, pnts, cmpt, 3tz, GeoJSON) has errors (listed as
    /// causes).
    CONTENT_VALIDATION_ERROR => Error,
    /// A tile content has warnings but no errors (listed as causes).
    CONTENT_VALIDATION_WARNING => Warning,
    /// A tile content has only notes (listed as causes).
    CONTENT_VALIDATION_INFO => Info,
    /// A b3dm / i3dm / pnts feature or batch table property that its format does not define, of
    /// the wrong shape, or outside its binary body.
    CONTENT_JSON_INVALID => Error,
    /// An external tileset refers back to itself or to a tileset that refers to it (a cycle).
    EXTERNAL_TILESET_CYCLE => Error,
    /// External tilesets nest deeper than --max-external-depth; the deeper ones are not opened.
    EXTERNAL_TILESET_TOO_DEEP => Error,
    /// Two properties of which at most one may be present are both present (content and
    /// contents, schema and schemaUri).
    ONE_OF_ERROR => Error,
    /// An element of an array has the wrong JSON type (a string in a bounding box, a child tile
    /// that is not an object).
    ARRAY_ELEMENT_TYPE_MISMATCH => Error,
    /// An array whose elements must be unique has a duplicate (extensionsUsed, extensionsRequired).
    ARRAY_ELEMENT_NOT_UNIQUE => Error,
    /// A required property is missing.
    PROPERTY_MISSING => Error,
    /// A property has the wrong JSON type.
    TYPE_MISMATCH => Error,
    /// An array has the wrong number of elements.
    ARRAY_LENGTH_MISMATCH => Error,
    /// An array has an allowed but unexpected length (an empty `children`: leave it out).
    ARRAY_LENGTH_UNEXPECTED => Warning,
    /// A number is outside its allowed range.
    VALUE_NOT_IN_RANGE => Error,
    /// A string is not one of the allowed values.
    VALUE_NOT_IN_LIST => Error,
    /// asset.version is neither "1.0" nor "1.1".
    ASSET_VERSION_UNKNOWN => Warning,
    /// The root tile has no refine value.
    TILE_REFINE_MISSING_IN_ROOT => Error,
    /// refine is ADD or REPLACE in the wrong case (`add`, `Replace`): read as meant, but a
    /// strict client refuses it.
    TILE_REFINE_WRONG_CASE => Warning,
    /// A bounding volume is malformed or degenerate.
    BOUNDING_VOLUME_INVALID => Error,
    /// A tile transform is not 16 finite numbers.
    TRANSFORM_INVALID => Error,
    /// A tile transform's last row is not (0, 0, 0, 1): not an affine transform.
    TRANSFORM_NOT_AFFINE => Error,
    /// A tile transform is affine but singular (its content collapses to a plane, line or point).
    TRANSFORM_SINGULAR => Info,
    /// A content bounding volume is not inside its tile's bounding volume.
    CONTENT_BOUNDING_VOLUME_NOT_IN_TILE => Error,
    /// A tile's geometric error is larger than its parent's.
    TILE_GEOMETRIC_ERRORS_INCONSISTENT => Warning,
    /// A tile without content has content below it and can end a REPLACE traversal (its region
    /// is then drawn empty): it needs a level-of-detail content, or its parent's bounding volume
    /// and geometric error.
    TILE_WITHOUT_CONTENT_ENDS_REFINEMENT => Warning,
    /// An implicit root has children, metadata or a content bounding volume, or its root
    /// subtree file is missing.
    TILE_IMPLICIT_ROOT_INVALID => Error,
    /// A template URI uses a variable that the subdivision scheme does not define.
    TEMPLATE_URI_INVALID_VARIABLE_NAME => Error,
    /// A template URI does not use every variable of the subdivision scheme.
    TEMPLATE_URI_MISSING_VARIABLE_NAME => Warning,
    /// The implicit tiling object is unusable (the walk of subtrees stops there).
    IMPLICIT_TILING_ERROR => Error,
    /// An extension is in extensionsRequired but not in extensionsUsed.
    EXTENSION_REQUIRED_BUT_NOT_USED => Error,
    /// An extension that clients cannot do without (MAXAR_content_3tz) is used but not required.
    EXTENSION_REQUIRED_BUT_NOT_DECLARED => Error,
    /// An extension object is present but its name is not in extensionsUsed.
    EXTENSION_FOUND_BUT_NOT_USED => Error,
    /// An `extras` member is not a JSON object.
    EXTRAS_UNEXPECTED_TYPE => Warning,
    /// An extension is in extensionsUsed but no object of the tileset carries it.
    EXTENSION_USED_BUT_NOT_FOUND => Warning,
    /// An extension in extensionsUsed is unknown to this validator: its objects are not checked.
    EXTENSION_NOT_SUPPORTED => Warning,
    /// A binary file has a bad magic or version.
    BINARY_INVALID => Error,
    /// A binary header's lengths disagree with the file size.
    BINARY_INVALID_LENGTH => Error,
    /// A chunk, padding or bufferView offset breaks the 8-byte alignment rule.
    BINARY_INVALID_ALIGNMENT => Error,
    /// A JSON chunk's padding is not spaces or a binary chunk's is not zeros.
    BINARY_INVALID_PADDING => Error,
    /// Buffers and bufferViews disagree (a view outside its buffer, a bad buffer index).
    BUFFERS_INCONSISTENT => Error,
    /// An availability object is not exactly one of bitstream / constant, or its bitstream is unusable.
    AVAILABILITY_INVALID => Error,
    /// Availability breaks a rule: tile without its parent, content without tile, wrong availableCount.
    SUBTREE_AVAILABILITY_INCONSISTENT => Error,
    /// A child subtree marked available has no file.
    SUBTREE_FILE_MISSING => Error,
    /// A subtree file exists for a child subtree marked unavailable (it is never loaded).
    SUBTREE_FILE_UNREFERENCED => Warning,
    /// A metadata schema identifier does not match `^[a-zA-Z_][a-zA-Z0-9_]*$`.
    IDENTIFIER_NOT_VALID => Error,
    /// A class property's type, componentType, array or count is invalid.
    CLASS_PROPERTY_TYPE_ERROR => Error,
    /// A property with a built-in semantic has the wrong type for that semantic.
    METADATA_SEMANTIC_INVALID => Error,
    /// A class property's semantic is not one of the 3D Metadata Semantic Reference.
    METADATA_SEMANTIC_UNKNOWN => Warning,
    /// A property table names an unknown class or property, or a missing bufferView.
    PROPERTY_TABLE_INVALID => Error,
    /// A property table's count differs from the number of available tiles or contents.
    PROPERTY_TABLE_COUNT_MISMATCH => Error,
    /// A property table column's bytes do not match count x element size.
    PROPERTY_TABLE_VALUES_INVALID => Error,
    /// A metadata value is invalid for its semantic (negative geometric error, bad box...).
    METADATA_VALUE_INVALID => Error,
    /// A metadata entity names a class the schema does not define (or there is no schema).
    METADATA_CLASS_UNKNOWN => Error,
    /// A metadata entity sets a property its class does not define.
    METADATA_PROPERTY_UNKNOWN => Error,
    /// A required class property has no value (and no default).
    METADATA_VALUE_REQUIRED_BUT_MISSING => Error,
    /// A metadata value does not have the JSON shape of its property (type, components, array
    /// length, enum name, integer range of the component type).
    METADATA_VALUE_TYPE_MISMATCH => Error,
    /// A metadata value (after offset and scale) lies outside the property's min / max.
    METADATA_VALUE_NOT_IN_RANGE => Error,
    /// A glb's header or chunks are malformed or truncated.
    GLB_INVALID => Error,
    /// A glTF index points to an object that does not exist.
    GLTF_REFERENCE_INVALID => Error,
    /// An accessor runs past its bufferView, or a bufferView past its buffer.
    ACCESSOR_OUT_OF_BOUNDS => Error,
    /// An accessor's offset or stride is not aligned to its component size (4 bytes for vertex attributes).
    ACCESSOR_ALIGNMENT_INVALID => Error,
    /// The attributes of one primitive have different counts.
    ACCESSOR_COUNT_MISMATCH => Error,
    /// POSITION has no min/max.
    ACCESSOR_MIN_MAX_MISSING => Error,
    /// Declared min/max differ from the data.
    ACCESSOR_MIN_MAX_MISMATCH => Error,
    /// An attribute has a type, componentType or normalization the extension does not allow.
    ACCESSOR_TYPE_INVALID => Error,
    /// An attribute holds NaN or infinite values.
    ACCESSOR_NON_FINITE => Error,
    /// No mesh primitive carries KHR_gaussian_splatting.
    SPLAT_PRIMITIVE_MISSING => Error,
    /// A KHR_gaussian_splatting primitive is not POINTS (mode 0).
    SPLAT_MODE_NOT_POINTS => Error,
    /// A required splat attribute is missing.
    SPLAT_ATTRIBUTE_MISSING => Error,
    /// An attribute in the KHR_gaussian_splatting namespace is not one the extension defines.
    SPLAT_ATTRIBUTE_UNKNOWN => Warning,
    /// Spherical harmonics with a partial degree or a missing lower degree.
    SPLAT_SH_INCOMPLETE => Error,
    /// OPACITY outside [0, 1].
    SPLAT_OPACITY_OUT_OF_RANGE => Error,
    /// SCALE negative or non-finite (log-space scales are negative).
    SPLAT_SCALE_INVALID => Error,
    /// ROTATION is not a unit quaternion within the tolerance.
    SPLAT_ROTATION_NOT_UNIT => Error,
    /// Attribute data carried by a compression extension was not decoded, so not checked.
    CONTENT_DATA_NOT_CHECKED => Info,
    /// A `S2T_gaussian_splatting_compression_codebook` payload that does not decode.
    SPLAT_CODEBOOK_PAYLOAD_INVALID => Error,
    /// A codebook payload whose splat count differs from the accessors' count.
    SPLAT_CODEBOOK_COUNT_MISMATCH => Error,
    /// More issues were found than a report lists (10 000); the rest were dropped.
    ISSUES_TRUNCATED => Info,
    /// A splat centre lies outside its tile's bounding volume.
    CONTENT_OUTSIDE_BOUNDING_VOLUME => Error,
    /// A splat's 3-sigma ellipsoid reaches outside its tile's bounding volume (--check-extent).
    CONTENT_EXTENT_OUTSIDE_BOUNDING_VOLUME => Warning,
    /// Layered contents (SPLAT2TILES_layer) in a tileset whose implicit root does not refine by ADD.
    LAYER_REFINE_NOT_ADD => Error,
    /// A layered tileset's root content is missing or is not a base layer (level 0, no deltas).
    LAYER_BASE_MISSING => Error,
    /// A content of a layered tileset lacks SPLAT2TILES_layer, or the extension is malformed.
    LAYER_EXTENSION_INVALID => Error,
    /// A layer's level is not its tile's level.
    LAYER_LEVEL_MISMATCH => Error,
    /// An enhancement layer's parent tile has no content to adjust.
    LAYER_PARENT_MISSING => Error,
    /// A delta accessor's count is not the splat count of the layer it adjusts (parent or ancestor).
    LAYER_DELTA_COUNT_MISMATCH => Error,
    /// An opacity delta below -1 (or not finite).
    LAYER_DELTA_OUT_OF_RANGE => Error,
    /// The deltas the descendant layers give one splat add up to less than -1.
    LAYER_DELTA_SUM_OUT_OF_RANGE => Error,
    /// An ancestorOpacityDeltas entry names a level not below the layer's level - 1, or an
    /// ancestor tile without content.
    LAYER_ANCESTOR_INVALID => Error,
    /// A sparse delta accessor's indices are out of range, not strictly increasing, or not
    /// UNSIGNED_INT (or its sparse storage is out of bounds).
    LAYER_SPARSE_INVALID => Error,
    /// A splat's stored opacity times (1 + its descendants' deltas) exceeds 1 (drawn capped at 1).
    LAYER_OPACITY_ABOVE_ONE => Warning,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_unique_upper_snake_with_fixed_severity() {
        let mut seen = std::collections::HashSet::new();
        for (code, _, doc) in CATALOGUE {
            assert!(seen.insert(*code), "duplicate {code}");
            assert!(
                code.chars()
                    .all(|c| c.is_ascii_uppercase() || c == '_' || c.is_ascii_digit())
            );
            assert!(!doc.is_empty(), "{code} has no doc");
        }
        assert_eq!(
            Issue::TILE_GEOMETRIC_ERRORS_INCONSISTENT("p", "m").severity,
            Severity::Warning
        );
        assert_eq!(Issue::IO_ERROR("p", "m").code, "IO_ERROR");
    }
}
