//! (brdf: not written yet)
