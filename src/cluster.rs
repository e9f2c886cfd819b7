//! (cluster: not written yet)
