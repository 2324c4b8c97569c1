pub mod geometry;
pub mod scenario;
