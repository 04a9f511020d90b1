//! Robots: the base, the parts (wheels, lasers, cameras, structural parts) and the joints
//! between them.

use std::collections::BTreeSet;

use oxrdf::NamedNodeRef;
use oxrdf::vocab::rdf;

use super::Reader;
use crate::model::{
    Camera, CameraKind, Joint, JointKind, Laser, Part, Robot, StructuralPart, Wheel,
};
use crate::vocab as v;

/// What a wheel's classes say it is.
#[derive(Copy, Clone)]
struct WheelKind {
    active: bool,
    passive: bool,
    caster: bool,
}

impl<'g> Reader<'g> {
    pub(super) fn robot(&mut self, iri: &str) -> Option<Robot> {
        let before = self.problems.len();
        let symbol = self.symbol(iri);
        let differential_drive = self.has_type(iri, v::DIFFERENTIAL_DRIVE_ROBOT);
        let max_linear_speed = self.positive(iri, v::MAX_LINEAR_SPEED_M_PER_S, false);
        let max_angular_speed = self.positive(iri, v::MAX_ANGULAR_SPEED_RAD_PER_S, false);
        let dynamics = crate::model::Dynamics {
            max_linear_acceleration: self.positive(iri, v::MAX_LINEAR_ACCELERATION_M_PER_S2, false),
            max_linear_deceleration: self.positive(iri, v::MAX_LINEAR_DECELERATION_M_PER_S2, false),
            max_angular_acceleration: self.positive(
                iri,
                v::MAX_ANGULAR_ACCELERATION_RAD_PER_S2,
                false,
            ),
            max_angular_deceleration: self.positive(
                iri,
                v::MAX_ANGULAR_DECELERATION_RAD_PER_S2,
                false,
            ),
            control_latency: self.positive(iri, v::CONTROL_LATENCY_S, false),
        };
        let base = self.iri(iri, v::HAS_BASE_PART, true);
        let mut part_iris: BTreeSet<String> = BTreeSet::new();
        for p in [v::HAS_PART, v::HAS_SENSOR, v::HAS_BASE_PART] {
            part_iris.extend(self.iris(iri, p));
        }
        let mut robot = Robot {
            iri: iri.to_owned(),
            symbol,
            differential_drive,
            max_linear_speed,
            max_angular_speed,
            dynamics,
            base: base.clone().unwrap_or_default(),
            structure: Vec::new(),
            wheels: Vec::new(),
            joints: Vec::new(),
            lasers: Vec::new(),
            cameras: Vec::new(),
        };
        for part in &part_iris {
            self.robot_part(iri, part, &mut robot);
        }
        if let Some(base) = &base {
            let is_structural = robot.structure.iter().any(|p| &p.part.iri == base)
                || robot.wheels.iter().any(|w| &w.part.iri == base);
            if !is_structural && self.problems.len() == before {
                self.problem(
                    iri,
                    v::HAS_BASE_PART,
                    format!("refers to <{base}>, which is not a structural part of this robot"),
                );
            }
        }
        for joint in &robot.joints {
            for (p, target) in [
                (v::HAS_PARENT_PART, &joint.parent),
                (v::HAS_CHILD_PART, &joint.child),
            ] {
                if !part_iris.contains(target) {
                    self.problem(
                        &joint.iri,
                        p,
                        format!("refers to <{target}>, which is not a part of robot <{iri}> (dangling reference)"),
                    );
                }
            }
            if joint.parent == joint.child {
                self.problem(
                    &joint.iri,
                    v::HAS_CHILD_PART,
                    "a joint must connect two different parts",
                );
            }
        }
        if self.problems.len() > before {
            return None;
        }
        Some(robot)
    }

    /// Reads part `iri` of `robot` into `out` by its class: a joint, wheel, structural part,
    /// laser range finder or camera; anything else (or a part the graph does not describe)
    /// is a problem.
    pub(super) fn robot_part(&mut self, robot: &str, iri: &str, out: &mut Robot) {
        let types = self.types(iri);
        let is = |r: &Self, c: NamedNodeRef<'_>| types.iter().any(|t| r.is_subclass(t, c));
        if types.is_empty() && !self.graph_describes(iri) {
            self.problem(
                robot,
                v::HAS_PART,
                format!(
                    "refers to <{iri}>, which the graph does not describe (dangling reference)"
                ),
            );
            return;
        }
        if is(self, v::JOINT) {
            if let Some(j) =
                self.joint(iri, is(self, v::CONTINUOUS_JOINT), is(self, v::FIXED_JOINT))
            {
                out.joints.push(j);
            }
            return;
        }
        if is(self, v::WHEEL) {
            let kind = WheelKind {
                active: is(self, v::ACTIVE_WHEEL),
                passive: is(self, v::PASSIVE_WHEEL),
                caster: is(self, v::CASTER_WHEEL),
            };
            if let Some(w) = self.wheel(iri, kind) {
                out.wheels.push(w);
            }
            return;
        }
        if is(self, v::STRUCTURAL_PART) {
            if let Some(part) = self.part(iri, true) {
                out.structure.push(StructuralPart { part });
            }
            return;
        }
        if is(self, v::LASER_RANGE_FINDER) {
            if let Some(l) = self.laser(iri) {
                out.lasers.push(l);
            }
            return;
        }
        if is(self, v::CAMERA) {
            let kind = if is(self, v::STEREO_CAMERA) {
                CameraKind::Stereo
            } else if is(self, v::RGBD_CAMERA) {
                CameraKind::RgbD
            } else {
                CameraKind::Mono
            };
            if let Some(c) = self.camera(iri, kind) {
                out.cameras.push(c);
            }
            return;
        }
        self.problem(
            iri,
            rdf::TYPE,
            format!(
                "is a part of robot <{robot}> but not a structural part, wheel, joint, camera or laser range finder"
            ),
        );
    }

    /// Wheel `iri`, whose classes say `kind`: exactly one of active and passive.
    fn wheel(&mut self, iri: &str, kind: WheelKind) -> Option<Wheel> {
        if kind.active == kind.passive {
            self.problem(
                iri,
                rdf::TYPE,
                "a wheel must be exactly one of tosm:ActiveWheel and tosm:PassiveWheel",
            );
        }
        let part = self.part(iri, true);
        let radius = self.positive(iri, v::WHEEL_RADIUS_M, true);
        let width = self.positive(iri, v::WHEEL_WIDTH_M, false);
        Some(Wheel {
            part: part?,
            active: kind.active,
            caster: kind.caster,
            radius: radius?,
            width,
        })
    }

    /// Laser range finder `iri`: its range (the minimum below the maximum), view angle,
    /// samples and resolution, and its rate when given.
    fn laser(&mut self, iri: &str) -> Option<Laser> {
        let part = self.part(iri, false);
        let range_min = self.non_negative(iri, v::RANGE_MIN_M, true);
        let range_max = self.positive(iri, v::RANGE_MAX_M, true);
        let view_angle = self.positive(iri, v::VIEW_ANGLE_RAD, true);
        let samples = self.count(iri, v::SAMPLE_COUNT, true);
        let angular_resolution = self.positive(iri, v::ANGULAR_RESOLUTION_RAD, true);
        let rate_hz = self.positive(iri, v::FRAME_RATE_HZ, false);
        if let (Some(min), Some(max)) = (range_min, range_max)
            && min >= max
        {
            self.problem(
                iri,
                v::RANGE_MAX_M,
                format!("must exceed rangeMinM ({min}), found {max}"),
            );
            return None;
        }
        Some(Laser {
            part: part?,
            range_min: range_min?,
            range_max: range_max?,
            view_angle: view_angle?,
            samples: samples?,
            angular_resolution: angular_resolution?,
            rate_hz,
        })
    }

    /// Camera `iri` of `kind`: its image, frame rate and fields of view, and for a depth
    /// camera its depth range (the minimum below the maximum).
    fn camera(&mut self, iri: &str, kind: CameraKind) -> Option<Camera> {
        let part = self.part(iri, false);
        let width_px = self.count(iri, v::IMAGE_WIDTH_PX, true);
        let height_px = self.count(iri, v::IMAGE_HEIGHT_PX, true);
        let fps = self.positive(iri, v::FRAME_RATE_HZ, true);
        let horizontal_fov = self.positive(iri, v::HORIZONTAL_FOV_RAD, true);
        let vertical_fov = self.positive(iri, v::VERTICAL_FOV_RAD, false);
        let depth = kind != CameraKind::Mono;
        let range_min = self.non_negative(iri, v::RANGE_MIN_M, depth);
        let range_max = self.positive(iri, v::RANGE_MAX_M, depth);
        let depth_range = match (range_min, range_max) {
            (Some(min), Some(max)) if min >= max => {
                self.problem(
                    iri,
                    v::RANGE_MAX_M,
                    format!("must exceed rangeMinM ({min}), found {max}"),
                );
                return None;
            }
            (Some(min), Some(max)) => Some((min, max)),
            _ => None,
        };
        let baseline = self.positive(iri, v::BASELINE_M, false);
        Some(Camera {
            part: part?,
            kind,
            width_px: width_px?,
            height_px: height_px?,
            fps: fps?,
            horizontal_fov: horizontal_fov?,
            vertical_fov,
            depth_range,
            baseline,
        })
    }

    pub(super) fn part(&mut self, iri: &str, structural: bool) -> Option<Part> {
        let symbol = self.symbol(iri);
        let mounting = self.pose(iri, v::HAS_MOUNTING_POSE, false);
        let mounting = match mounting {
            Some(p) => Some(p),
            None if self.objects(iri, v::HAS_MOUNTING_POSE).is_empty() => {
                self.pose(iri, v::HAS_POSE, false).or_else(|| {
                    if self.objects(iri, v::HAS_POSE).is_empty() {
                        self.problem(iri, v::HAS_MOUNTING_POSE, "is missing (required)");
                    }
                    None
                })
            }
            None => None,
        };
        let shape = self.shape(iri, false);
        let colour = self.colour(iri);
        let physical = self.physical(iri, structural);
        Some(Part {
            iri: iri.to_owned(),
            symbol,
            mounting: mounting?,
            shape,
            colour,
            physical,
        })
    }

    pub(super) fn joint(&mut self, iri: &str, continuous: bool, fixed: bool) -> Option<Joint> {
        let symbol = self.symbol(iri);
        let kind = match (continuous, fixed) {
            (true, false) => JointKind::Continuous,
            (false, true) => JointKind::Fixed,
            _ => {
                self.problem(
                    iri,
                    rdf::TYPE,
                    "a joint must be exactly one of tosm:FixedJoint and tosm:ContinuousJoint",
                );
                return None;
            }
        };
        let parent = self.iri(iri, v::HAS_PARENT_PART, true);
        let child = self.iri(iri, v::HAS_CHILD_PART, true);
        let ax = self.number(iri, v::AXIS_X, false);
        let ay = self.number(iri, v::AXIS_Y, false);
        let az = self.number(iri, v::AXIS_Z, false);
        let axis = match (ax, ay, az) {
            (None, None, None) => [0.0, 1.0, 0.0],
            (x, y, z) => [x.unwrap_or(0.0), y.unwrap_or(0.0), z.unwrap_or(0.0)],
        };
        if axis.iter().all(|c| *c == 0.0) {
            self.problem(iri, v::AXIS_Y, "a joint axis cannot be the zero vector");
        }
        Some(Joint {
            iri: iri.to_owned(),
            symbol,
            kind,
            parent: parent?,
            child: child?,
            axis,
        })
    }
}
