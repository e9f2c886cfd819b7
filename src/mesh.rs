//! (mesh: not written yet)
