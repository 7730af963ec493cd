//! The IST stage's error: a link with no room for a sphere, or a tree its validation refuses.

use super::validate;

#[derive(Debug, thiserror::Error)]
pub enum IstError {
    #[error("link {link}: no inner sphere fits (every element is thinner than 2 × min_radius_m = {min_radius_m} m)")]
    NoSpheres { link: String, min_radius_m: f32 },
    #[error("the tree fails its validation and is refused (not cached, not used): {0}")]
    Invalid(#[from] validate::ValidationError),
}
