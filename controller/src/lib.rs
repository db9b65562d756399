//! The scanhil host.

pub mod accuracy;
pub mod continuous;
pub mod discretise;
pub mod dual_tone;
pub mod identify;
pub mod imaging;
pub mod link;
pub mod loop_analysis;
pub mod pid;
pub mod plant_model;
pub mod run;
pub mod scan_controller;
pub mod settings;
pub mod sos;
pub mod trajectory;
