//! (points: not written yet)
