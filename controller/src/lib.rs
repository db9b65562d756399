//! The scanhil host.
