//! The motion-imitation baseline's data: raw dog motion capture ([`mocap`]), its retargeting to
//! the A1 ([`retarget`]), the reference-motion file and its loop ([`motion`]), and the
//! speed-scaled reference a policy follows ([`reference`]).

pub mod mocap;
pub mod motion;
pub mod reference;
pub mod retarget;
