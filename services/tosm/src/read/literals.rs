//! Single values (numbers, strings, IRIs, each checked against its range) and the small
//! descriptions built of them that every model shares: symbol, pose, shape, colour, physical.

use base64::Engine as _;
use oxrdf::vocab::{rdf, xsd};
use oxrdf::{NamedNodeRef, TermRef};

use super::{EXTENT_TOLERANCE, Reader};
use crate::model::{Colour, Physical, Pose3, Shape, Symbol};
use crate::vocab as v;

/// The XSD integer datatypes a count or a number may be written in.
const INTEGER_TYPES: &[NamedNodeRef<'static>] = &[
    xsd::INTEGER,
    xsd::INT,
    xsd::LONG,
    xsd::SHORT,
    xsd::NON_NEGATIVE_INTEGER,
    xsd::POSITIVE_INTEGER,
    xsd::NON_POSITIVE_INTEGER,
    xsd::NEGATIVE_INTEGER,
    xsd::UNSIGNED_INT,
    xsd::UNSIGNED_LONG,
];

impl<'g> Reader<'g> {
    pub(super) fn objects(&self, s: &str, p: NamedNodeRef<'_>) -> Vec<TermRef<'g>> {
        let mut v: Vec<TermRef<'g>> = self
            .graph
            .objects_for_subject_predicate(NamedNodeRef::new_unchecked(s), p)
            .collect();
        v.sort_by_key(|t| t.to_string());
        v
    }

    /// The one value of a functional property; reports a missing (when required) or repeated one.
    pub(super) fn one(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
    ) -> Option<TermRef<'g>> {
        let values = self.objects(s, p);
        match values.as_slice() {
            [] => {
                if required {
                    self.problem(s, p, "is missing (required)");
                }
                None
            }
            [one] => Some(*one),
            many => {
                let shown: Vec<String> = many.iter().map(ToString::to_string).collect();
                self.problem(
                    s,
                    p,
                    format!(
                        "has {} values ({}), expected exactly one",
                        many.len(),
                        shown.join(", ")
                    ),
                );
                None
            }
        }
    }

    pub(super) fn literal(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
    ) -> Option<(String, String)> {
        match self.one(s, p, required)? {
            TermRef::Literal(l) => Some((l.value().to_owned(), l.datatype().as_str().to_owned())),
            other => {
                self.problem(s, p, format!("must be a literal, found {other}"));
                None
            }
        }
    }

    pub(super) fn number(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<f64> {
        let (value, datatype) = self.literal(s, p, required)?;
        let numeric = [xsd::DECIMAL, xsd::DOUBLE, xsd::FLOAT]
            .iter()
            .chain(INTEGER_TYPES)
            .any(|d| d.as_str() == datatype);
        let parsed = if numeric {
            value.trim().parse::<f64>().ok()
        } else {
            None
        };
        match parsed {
            Some(x) if x.is_finite() => Some(x),
            Some(_) => {
                self.problem(s, p, format!("must be a finite number, found {value:?}"));
                None
            }
            None => {
                self.problem(
                    s,
                    p,
                    format!("must be a number (xsd:decimal), found {value:?} of type <{datatype}>"),
                );
                None
            }
        }
    }

    /// A number that must satisfy `ok`, described by `range` in the problem otherwise.
    pub(super) fn number_where(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
        ok: fn(f64) -> bool,
        range: &str,
    ) -> Option<f64> {
        let x = self.number(s, p, required)?;
        if ok(x) {
            Some(x)
        } else {
            self.problem(s, p, format!("must be {range}, found {x}"));
            None
        }
    }

    pub(super) fn positive(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<f64> {
        self.number_where(s, p, required, |x| x > 0.0, "> 0")
    }

    pub(super) fn non_negative(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
    ) -> Option<f64> {
        self.number_where(s, p, required, |x| x >= 0.0, ">= 0")
    }

    pub(super) fn unit_interval(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
    ) -> Option<f64> {
        self.number_where(s, p, required, |x| (0.0..=1.0).contains(&x), "in [0, 1]")
    }

    pub(super) fn integer(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<i64> {
        let (value, datatype) = self.literal(s, p, required)?;
        let parsed = if INTEGER_TYPES.iter().any(|d| d.as_str() == datatype) {
            value.trim().trim_start_matches('+').parse::<i64>().ok()
        } else {
            None
        };
        if parsed.is_none() {
            self.problem(
                s,
                p,
                format!("must be an integer (xsd:integer), found {value:?} of type <{datatype}>"),
            );
        }
        parsed
    }

    pub(super) fn count(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<u32> {
        let n = self.integer(s, p, required)?;
        match u32::try_from(n) {
            Ok(n) if n > 0 => Some(n),
            _ => {
                self.problem(s, p, format!("must be a whole number >= 1, found {n}"));
                None
            }
        }
    }

    pub(super) fn boolean(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<bool> {
        let (value, datatype) = self.literal(s, p, required)?;
        match (datatype == xsd::BOOLEAN.as_str(), value.trim()) {
            (true, "true" | "1") => Some(true),
            (true, "false" | "0") => Some(false),
            _ => {
                self.problem(
                    s,
                    p,
                    format!(
                        "must be a boolean (xsd:boolean), found {value:?} of type <{datatype}>"
                    ),
                );
                None
            }
        }
    }

    pub(super) fn string(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
    ) -> Option<String> {
        let (value, datatype) = self.literal(s, p, required)?;
        if datatype == xsd::STRING.as_str() || datatype == rdf::LANG_STRING.as_str() {
            Some(value)
        } else {
            self.problem(
                s,
                p,
                format!("must be a string, found {value:?} of type <{datatype}>"),
            );
            None
        }
    }

    /// The first of possibly several strings (names may come in several languages).
    pub(super) fn first_string(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
    ) -> Option<String> {
        let values = self.objects(s, p);
        let strings: Vec<String> = values
            .iter()
            .filter_map(|t| match t {
                TermRef::Literal(l) => Some(l.value().to_owned()),
                _ => None,
            })
            .collect();
        if strings.len() != values.len() {
            self.problem(s, p, "must be a string literal, found an IRI or blank node");
        }
        if strings.is_empty() && values.is_empty() && required {
            self.problem(s, p, "is missing (required)");
        }
        strings.into_iter().next()
    }

    pub(super) fn iri(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<String> {
        match self.one(s, p, required)? {
            TermRef::NamedNode(n) => Some(n.as_str().to_owned()),
            other => {
                self.problem(s, p, format!("must be an IRI, found {other}"));
                None
            }
        }
    }

    pub(super) fn iris(&mut self, s: &str, p: NamedNodeRef<'_>) -> Vec<String> {
        let mut out = Vec::new();
        for t in self.objects(s, p) {
            match t {
                TermRef::NamedNode(n) => out.push(n.as_str().to_owned()),
                other => self.problem(s, p, format!("must be an IRI, found {other}")),
            }
        }
        out.sort();
        out.dedup();
        out
    }

    pub(super) fn symbol(&mut self, s: &str) -> Symbol {
        Symbol {
            name: self.first_string(s, v::NAME, true).unwrap_or_default(),
            identifier: self.string(s, v::IDENTIFIER, false),
            description: self.first_string(s, v::DESCRIPTION, false),
        }
    }

    pub(super) fn pose(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<Pose3> {
        let pose = self.iri(s, p, required)?;
        if !self.has_type(&pose, v::POSE) && !self.graph_describes(&pose) {
            self.problem(
                s,
                p,
                format!("refers to <{pose}>, which the graph does not describe"),
            );
            return None;
        }
        let x = self.number(&pose, v::X_M, true);
        let y = self.number(&pose, v::Y_M, true);
        let z = self.number(&pose, v::Z_M, false).unwrap_or(0.0);
        let roll = self.number(&pose, v::ROLL_RAD, false).unwrap_or(0.0);
        let pitch = self.number(&pose, v::PITCH_RAD, false).unwrap_or(0.0);
        let yaw = self.number(&pose, v::YAW_RAD, false).unwrap_or(0.0);
        Some(Pose3 {
            x: x?,
            y: y?,
            z,
            roll,
            pitch,
            yaw,
        })
    }

    pub(super) fn shape(&mut self, s: &str, required: bool) -> Option<Shape> {
        let shape = self.iri(s, v::HAS_SHAPE, required)?;
        let types = self.types(&shape);
        let kinds: Vec<NamedNodeRef<'static>> = [v::BOX_SHAPE, v::CYLINDER_SHAPE, v::SPHERE_SHAPE]
            .into_iter()
            .filter(|k| types.iter().any(|t| self.is_subclass(t, *k)))
            .collect();
        let kind = match kinds.as_slice() {
            [k] => *k,
            [] => {
                self.problem(
                    &shape,
                    rdf::TYPE,
                    "must be a tosm:BoxShape, tosm:CylinderShape or tosm:SphereShape",
                );
                return None;
            }
            _ => {
                self.problem(&shape, rdf::TYPE, "has more than one shape class");
                return None;
            }
        };
        let length = self.positive(&shape, v::LENGTH_M, true);
        let width = self.positive(&shape, v::WIDTH_M, true);
        let height = self.positive(&shape, v::HEIGHT_M, true);
        let (length, width, height) = (length?, width?, height?);
        if kind == v::BOX_SHAPE {
            return Some(Shape::Box {
                length,
                width,
                height,
            });
        }
        if (length - width).abs() > EXTENT_TOLERANCE {
            self.problem(
                &shape,
                v::WIDTH_M,
                format!("must equal lengthM ({length}) for a round shape, found {width}"),
            );
            return None;
        }
        if kind == v::CYLINDER_SHAPE {
            return Some(Shape::Cylinder {
                diameter: length,
                height,
            });
        }
        if (length - height).abs() > EXTENT_TOLERANCE {
            self.problem(
                &shape,
                v::HEIGHT_M,
                format!("must equal lengthM ({length}) for a sphere, found {height}"),
            );
            return None;
        }
        Some(Shape::Sphere { diameter: length })
    }

    pub(super) fn colour(&mut self, s: &str) -> Option<Colour> {
        let r = self.unit_interval(s, v::COLOUR_RED, false);
        let g = self.unit_interval(s, v::COLOUR_GREEN, false);
        let b = self.unit_interval(s, v::COLOUR_BLUE, false);
        let a = self.unit_interval(s, v::COLOUR_ALPHA, false);
        match (r, g, b) {
            (Some(r), Some(g), Some(b)) => Some(Colour {
                r,
                g,
                b,
                a: a.unwrap_or(1.0),
            }),
            (None, None, None) => None,
            _ => {
                let mut missing = Vec::new();
                for (p, x) in [
                    (v::COLOUR_RED, r),
                    (v::COLOUR_GREEN, g),
                    (v::COLOUR_BLUE, b),
                ] {
                    if x.is_none() && self.objects(s, p).is_empty() {
                        missing.push(p);
                    }
                }
                for p in missing {
                    self.problem(s, p, "is missing: a colour needs red, green and blue");
                }
                None
            }
        }
    }

    pub(super) fn physical(&mut self, s: &str, required: bool) -> Physical {
        let mass_kg = self.positive(s, v::MASS_KG, required);
        let material = self.iri(s, v::HAS_MATERIAL, required);
        if let Some(m) = &material {
            let known =
                self.has_type(m, v::MATERIAL) || v::ALL.iter().any(|(_, term)| term.as_str() == m);
            if !known {
                self.problem(
                    s,
                    v::HAS_MATERIAL,
                    format!("refers to <{m}>, which is not a tosm:Material"),
                );
            }
        }
        Physical {
            mass_kg,
            material,
            friction: self.non_negative(s, v::FRICTION_COEFFICIENT, false),
        }
    }

    pub(super) fn base64(&mut self, s: &str, p: NamedNodeRef<'_>) -> Option<Vec<u8>> {
        let (value, _) = self.literal(s, p, true)?;
        let compact: String = value.chars().filter(|c| !c.is_ascii_whitespace()).collect();
        match base64::engine::general_purpose::STANDARD.decode(compact.as_bytes()) {
            Ok(bytes) => Some(bytes),
            Err(e) => {
                self.problem(s, p, format!("must be base64 (xsd:base64Binary): {e}"));
                None
            }
        }
    }
}
