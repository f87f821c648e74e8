//! Error type of the `leg` module.

use std::path::PathBuf;
use thiserror::Error;

/// Everything that can go wrong while loading a leg model or building its simulation.
///
/// Every variant names the offending URDF element (link, joint, loop closure or actuator) so
/// that the message alone is enough to locate the problem in the file.
#[derive(Debug, Error)]
pub enum LegError {
    /// The URDF file could not be read.
    #[error("cannot read URDF file {path}: {source}")]
    Io {
        /// Path that was given.
        path: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The text is not well-formed XML.
    #[error("malformed XML: {0}")]
    Xml(String),
    /// The XML is well formed but urdf-rs rejected it (missing required attribute, bad number...).
    #[error("invalid URDF: {0}")]
    Urdf(String),
    /// A required element or attribute is absent.
    #[error("missing {what}")]
    Missing {
        /// Description of the missing element/attribute, e.g. `<loop_closure> element`.
        what: String,
    },
    /// An element references a link that does not exist.
    #[error("{element} references unknown link '{link}'")]
    UnknownLink {
        /// The referencing element, e.g. `loop_closure 'rod_end' link1`.
        element: String,
        /// The name that was not found.
        link: String,
    },
    /// An element references a joint that does not exist.
    #[error("{element} references unknown joint '{joint}'")]
    UnknownJoint {
        /// The referencing element.
        element: String,
        /// The name that was not found.
        joint: String,
    },
    /// A joint is of the wrong type for its role.
    #[error("joint '{joint}' used as {role} must be {expected}, found {found}")]
    WrongJointType {
        /// Joint name.
        joint: String,
        /// Its role (`actuator 'knee_cylinder'`, `knee`...).
        role: String,
        /// Expected type(s).
        expected: String,
        /// Actual URDF type.
        found: String,
    },
    /// Zero, negative or non-finite mass.
    #[error("link '{link}' has non-positive mass {mass} kg")]
    NonPositiveMass {
        /// Link name.
        link: String,
        /// The mass read, kg.
        mass: f64,
    },
    /// The inertia tensor is not symmetric positive semi-definite.
    #[error("link '{link}' inertia tensor is not positive semi-definite (eigenvalues {eigenvalues:?} kg m^2)")]
    InertiaNotPositiveDefinite {
        /// Link name.
        link: String,
        /// Eigenvalues (kg m^2).
        eigenvalues: [f64; 3],
    },
    /// A body that moves (a link on a movable joint, with the links fixed to it) has no mass.
    #[error("moving body '{link}' (links {links:?}) has no mass: give one of its links an <inertial> mass")]
    MovingBodyWithoutMass {
        /// The link on the movable joint.
        link: String,
        /// Every link welded into the body.
        links: Vec<String>,
    },
    /// A body that moves has no rotational inertia (a point mass on a movable joint).
    #[error("moving body '{link}' (links {links:?}) has no rotational inertia (eigenvalues {eigenvalues:?} kg m^2)")]
    MovingBodyWithoutInertia {
        /// The link on the movable joint.
        link: String,
        /// Every link welded into the body.
        links: Vec<String>,
        /// Eigenvalues of its inertia about its centre of mass (kg m^2).
        eigenvalues: [f64; 3],
    },
    /// A value in the URDF is not finite, out of range or inconsistent.
    #[error("{element}: {message}")]
    Invalid {
        /// The element, e.g. `joint 'knee'`.
        element: String,
        /// What is wrong.
        message: String,
    },
    /// The joint graph is not a single tree.
    #[error("kinematic structure is not a tree: {0}")]
    NotATree(String),
    /// The model is not planar in the sagittal (x-z) plane, or its topology is not the
    /// knee + cylinder loop this module supports.
    #[error("unsupported model: {0}")]
    Unsupported(String),
    /// The cylinder cannot reach the shank mounting point at some knee angle.
    #[error("actuator '{actuator}': no geometric solution at knee angle {knee_rad} rad ({reason})")]
    Unreachable {
        /// Actuator name.
        actuator: String,
        /// Knee angle where it fails, rad.
        knee_rad: f64,
        /// Explanation, e.g. the required prismatic coordinate and the joint limits.
        reason: String,
    },
    /// Invalid argument passed to the API (e.g. non-positive time step).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}
