#![no_main]

#[path = "../targets.rs"]
mod targets;

#[global_allocator]
static ALLOCATOR: targets::Limited = targets::Limited(targets::LIMIT);

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::params(data));
