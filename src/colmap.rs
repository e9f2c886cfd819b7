//! (colmap: not written yet)
