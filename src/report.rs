//! (report: not written yet)
