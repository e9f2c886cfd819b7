//! (photo: not written yet)
