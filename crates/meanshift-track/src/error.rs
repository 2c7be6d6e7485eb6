//! The one error type of this crate.

/// Everything that can go wrong in `meanshift-track`.
///
/// No function of this crate panics on bad input: it returns one of these, naming what is
/// wrong (the marker, the window, the sizes involved).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TrackError {
    /// A window has no area (`width` or `height` is zero or negative).
    #[error("window {what} has no area: {width}x{height} px")]
    EmptyWindow {
        /// Which window (a marker id, or the argument name).
        what: String,
        /// Width in pixels as given.
        width: i32,
        /// Height in pixels as given.
        height: i32,
    },
    /// A window does not overlap the image (or, for the tracker's initial windows, is not
    /// entirely inside it).
    #[error(
        "window {what} at ({x}, {y}) size {width}x{height} px is outside the {image_width}x{image_height} image"
    )]
    WindowOutsideImage {
        /// Which window (a marker id, or the argument name).
        what: String,
        /// Left column as given.
        x: i32,
        /// Top row as given.
        y: i32,
        /// Width in pixels.
        width: i32,
        /// Height in pixels.
        height: i32,
        /// Image width in pixels.
        image_width: u32,
        /// Image height in pixels.
        image_height: u32,
    },
    /// Two images (or an image and a mask or depth map) that must have the same size do not.
    #[error(
        "{what}: expected {expected_width}x{expected_height} px, found {found_width}x{found_height} px"
    )]
    SizeMismatch {
        /// What was compared (`"frame 12"`, `"mask"`, `"depth map"`).
        what: String,
        /// Expected width in pixels.
        expected_width: u32,
        /// Expected height in pixels.
        expected_height: u32,
        /// Width found.
        found_width: u32,
        /// Height found.
        found_height: u32,
    },
    /// An image has no pixels.
    #[error("{what} is empty (0 pixels)")]
    EmptyImage {
        /// Which image.
        what: String,
    },
    /// An image has a channel count that the operation cannot use.
    #[error("{what}: needs {expected} channel(s), the image has {found}")]
    ChannelCount {
        /// The operation or argument.
        what: String,
        /// Channels the operation needs (in words, e.g. `"1"` or `"at least 3"`).
        expected: String,
        /// Channels the image has.
        found: usize,
    },
    /// A configuration or call parameter is outside its domain.
    #[error("invalid {name}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: String,
        /// What is wrong with its value.
        reason: String,
    },
    /// Two markers share an id.
    #[error("marker id {id:?} is used more than once")]
    DuplicateId {
        /// The repeated id.
        id: String,
    },
    /// A marker id that the tracker does not know.
    #[error("no marker with id {id:?}")]
    UnknownMarker {
        /// The id asked for.
        id: String,
    },
    /// The initial window of a marker holds nothing the appearance model can describe (for
    /// example, no pixel passes the saturation/value mask), so there is nothing to track.
    #[error("marker {id:?}: the initial window holds no usable pixels ({reason})")]
    EmptyModel {
        /// The marker.
        id: String,
        /// Why, in words.
        reason: String,
    },
}

impl TrackError {
    pub(crate) fn param(name: &str, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name: name.to_string(),
            reason: reason.into(),
        }
    }
}

/// Result with [`TrackError`].
pub type Result<T, E = TrackError> = std::result::Result<T, E>;
