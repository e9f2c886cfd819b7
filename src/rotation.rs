//! (rotation: not written yet)
