//! (workspace: not written yet)
