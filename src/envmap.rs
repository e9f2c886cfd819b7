//! (envmap: not written yet)
