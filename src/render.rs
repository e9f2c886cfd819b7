//! (render: not written yet)
