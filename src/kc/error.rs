//! Why a key comparison cannot be evaluated: one error type for every refusal of
//! [`super::evaluate`], [`super::link`] and the options, each naming the file, line and
//! column where it has them.

use crate::input::limits::sig;
use crate::results::Quantity;

/// Why a key comparison cannot be evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum KcError {
    /// Fewer than two laboratories.
    #[error("a key comparison needs at least 2 laboratories, {0} given")]
    TooFewLabs(usize),
    /// One pilot repeat only.
    #[error("the pilot's stability needs at least 2 repeated results, {0} given")]
    TooFewRepeats(usize),
    /// Two results with one name.
    #[error("the laboratory name {name:?} is given twice ({first} and {second})")]
    DuplicateName {
        /// The name.
        name: String,
        /// The first result of that name.
        first: String,
        /// The second.
        second: String,
    },
    /// A result without a row of the compared quantity.
    #[error("{file} (laboratory {lab}) has no {quantity} rows")]
    NoRows {
        /// The laboratory.
        lab: String,
        /// Its file.
        file: String,
        /// The quantity.
        quantity: Quantity,
    },
    /// A face between 1 and the last is missing.
    #[error(
        "{location}: the last face is {faces}, but pitch_deviation of face {face} is missing \
         (faces 1 … {faces} expected)"
    )]
    FaceMissing {
        /// `file:line:column` of the last face's index.
        location: String,
        /// The missing face.
        face: u32,
        /// The last face of the file.
        faces: u32,
    },
    /// Two results of polygons with different numbers of faces.
    #[error(
        "{location}: {faces} faces, but {first_source} has {first_faces}: every result must be \
         of the same polygon"
    )]
    FacesDiffer {
        /// `file:line:column` of the last face's index.
        location: String,
        /// Its number of faces.
        faces: u32,
        /// The first result.
        first_source: String,
        /// Its number of faces.
        first_faces: u32,
    },
    /// A quantity appears twice in one result.
    #[error("{location}: {quantity} {index} appears twice")]
    Duplicate {
        /// `file:line:column` of the index.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
    },
    /// An uncertainty that is not positive.
    #[error(
        "{location}: {quantity} {index} has {column} = {value}: a key comparison needs a \
         positive uncertainty (column {column})"
    )]
    NonPositiveUncertainty {
        /// `file:line:column` of the uncertainty.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// `U` or `u`.
        column: &'static str,
        /// The value.
        value: f64,
    },
    /// A row without a standard uncertainty.
    #[error(
        "{location}: {quantity} {index} has no standard uncertainty: a key comparison needs \
         u, or U with its k (columns u, U, k)"
    )]
    MissingUncertainty {
        /// `file:line:column` where the uncertainty is missing.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
    },
    /// No position (encoder angle or angle block) is compared: none is reported by two
    /// laboratories (comparing results: by every result).
    #[error(
        "no position is compared: none is reported by two laboratories (comparing results: by \
         every result); nothing to compare"
    )]
    NothingInCommon,
    /// A file that is not a solve result in JSON.
    #[error("{file}: not a solve result in JSON (docs/FORMAT.md §5.1): {message}")]
    SolveJson {
        /// The file.
        file: String,
        /// What is wrong, with serde's line and column where it has them.
        message: String,
    },
    /// A laboratory's covariance of its pitch deviations that cannot be used.
    #[error(
        "{file} (laboratory {lab}): its covariance of the pitch deviations is refused: {reason}"
    )]
    Covariance {
        /// The file.
        file: String,
        /// The laboratory.
        lab: String,
        /// Why, in words.
        reason: String,
    },
    /// Fewer than two compared positions: no closed vector.
    #[error(
        "{0} position(s) in common: a key comparison compares closed vectors of at least 2 \
         positions"
    )]
    TooFewPositions(usize),
    /// A laboratory to keep that is not among the laboratories.
    #[error("the laboratory {0:?} to keep is not among the laboratories")]
    UnknownKeep(String),
    /// A laboratory to keep out of the reference that is not among the laboratories.
    #[error("the laboratory {0:?} to keep out of the reference is not among the laboratories")]
    UnknownNotInReference(String),
    /// A laboratory both held in the reference and kept out of it.
    #[error("the laboratory {0:?} is both held in the reference and kept out of it")]
    KeptAndKeptOut(String),
    /// Fewer than two laboratories left for the reference.
    #[error(
        "{0} laboratory(ies) left for the reference once those kept out are set aside: a \
         reference needs at least 2"
    )]
    TooFewInReference(usize),
    /// A standard uncertainty below what the comparison computes with.
    #[error(
        "{location}: {quantity} {index} has u = {value:e}″, below {minimum:e}″: an angle's \
         uncertainty that small is not a measured one (a unit mistake?)"
    )]
    UncertaintyTooSmall {
        /// `file:line:column` of the uncertainty.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// The standard uncertainty.
        value: f64,
        /// The smallest accepted.
        minimum: f64,
    },
    /// The closed vector could not be computed.
    #[error("{0}")]
    NotComputable(String),
    /// Monte Carlo draws that cannot be made, and why.
    #[error("Monte Carlo U refused: {0}")]
    MonteCarlo(String),
    /// A comparison that cannot be linked to the other, and why.
    #[error("the comparisons cannot be linked: {0}")]
    Link(String),
    /// A quantity that is not compared ([`super::COMPARED_QUANTITIES`]).
    #[error(
        "a key comparison is of {compared}, not {0} (face deviations follow from the pitch \
         deviations; setup errors depend on the mounting)",
        compared = super::shared::compared_names()
    )]
    Quantity(Quantity),
    /// No compared quantity has rows in every result ([`super::shared_quantities`]).
    #[error(
        "no quantity a key comparison compares ({quantities}) has rows in every result: {}",
        lacking.join("; ")
    )]
    NoSharedQuantity {
        /// The compared quantities' names, in words.
        quantities: String,
        /// Per compared quantity, the results that lack it: `no encoder_error rows in
        /// B.csv (laboratory B)`.
        lacking: Vec<String>,
    },
    /// A result one face short of another: its last face is missing.
    #[error(
        "{location}: {quantity} of face {face} is missing: this result ends at face {}, and \
         {other_source} has faces 1 … {face}",
        face - 1
    )]
    LastFaceMissing {
        /// `file:line:column` of the result's last face's index.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// The missing face (the other result's last).
        face: u32,
        /// A result that has it.
        other_source: String,
    },
    /// An encoder error without a table angle beside results with angles.
    #[error(
        "{location}: encoder_error {index} has no angle_deg, but {with_angles} gives the table \
         angle of its encoder errors: results are matched by angle when they carry angles, so \
         every encoder error of every result needs angle_deg (or none, to be matched by index)"
    )]
    AngleMissing {
        /// `file:line:column` of the row's index (the first row without an angle).
        location: String,
        /// Its index.
        index: u32,
        /// A result whose encoder errors carry angles.
        with_angles: String,
    },
    /// Pitch deviations whose sum is far from 0 (docs/FORMAT.md §12): taking out their
    /// mean would move every face by more than the result's own expanded uncertainty.
    #[error(
        "{file} (laboratory {lab}): its pitch deviations sum to {}″ over {faces} faces, but a \
         polygon's pitch deviations sum to 0: taking out their mean would move every face by \
         {}″, more than the result's expanded uncertainty 2u = {}″ of face {face} (face \
         deviations given as pitch deviations, a face left out, a sign or a nominal angle \
         wrong?)",
        sig(*.sum_arcsec, 4),
        sig(.sum_arcsec.abs() / *.faces as f64, 3),
        sig(2.0 * *.u_arcsec, 3)
    )]
    NotClosed {
        /// The result's file.
        file: String,
        /// The laboratory (or the pilot's repeat).
        lab: String,
        /// Σβ, arcsec.
        sum_arcsec: f64,
        /// The number of faces N.
        faces: usize,
        /// The smallest standard uncertainty of the result's faces, arcsec.
        u_arcsec: f64,
        /// Its face.
        face: u32,
    },
    /// One of the pilot's repeats does not report an angle block the laboratories compare.
    #[error(
        "{location}: the pilot's repeat {repeat} has no angle_block {block} (here is its last \
         angle_block row): the pilot's repeats report every block compared (their spread is \
         the artefact's stability on each)"
    )]
    RepeatMissesBlock {
        /// Where the repeat's last row of angle blocks is (file:line:column of its index).
        location: String,
        /// The repeat's name.
        repeat: String,
        /// The block it lacks.
        block: u32,
    },
    /// Two results state different nominal angles for one angle block.
    #[error(
        "{location}: angle_block {block} has nominal_deg {nominal_deg}, but \
         {first_nominal_deg} at {first_location}: the same block has one nominal angle"
    )]
    NominalsDiffer {
        /// Where the second nominal angle is (file:line:column).
        location: String,
        /// The block.
        block: u32,
        /// Its nominal angle there, degrees.
        nominal_deg: f64,
        /// The first nominal angle stated, degrees.
        first_nominal_deg: f64,
        /// Where that is.
        first_location: String,
    },
    /// One of the pilot's repeats does not report an encoder position the laboratories
    /// compare.
    #[error(
        "{location}: the pilot's repeat {repeat} has no encoder_error at {position} (here is \
         its last encoder_error row): the pilot's repeats report every position compared \
         (their spread is the artefact's stability on each)"
    )]
    RepeatMissesPosition {
        /// Where the repeat's last row of encoder errors is (file:line:column of its index).
        location: String,
        /// The repeat's name.
        repeat: String,
        /// The position it lacks (a table angle, or an index).
        position: String,
    },
    /// A laboratory none (or, for a closed vector, fewer than two) of whose positions is
    /// compared: a position counts where another laboratory reports it too, and a result
    /// closed over one position holds no difference.
    #[error(
        "{file} (laboratory {lab}): {compared} of its {quantity} positions compared, fewer \
         than {needed} (a position counts where another laboratory reports it too; a result \
         closed over one position holds no difference), so it cannot be compared; leave it \
         out of the comparison of {quantity}"
    )]
    LabNotCompared {
        /// The laboratory.
        lab: String,
        /// Its file.
        file: String,
        /// The compared quantity.
        quantity: Quantity,
        /// How many of its positions are compared.
        compared: usize,
        /// How many are needed: 1 for angle blocks, 2 for a closed vector.
        needed: usize,
    },
    /// Laboratories whose positions fall into groups that share none: no one reference.
    #[error(
        "the laboratories fall into groups that share no {quantity} position: {groups}; \
         results defined up to a constant cannot be put on one reference across such groups"
    )]
    PositionsApart {
        /// The compared quantity.
        quantity: Quantity,
        /// The groups, named.
        groups: String,
    },
}
