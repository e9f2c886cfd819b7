//! (qp: not written yet)
