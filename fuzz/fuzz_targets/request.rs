#![no_main]
//! cargo-fuzz target: riskplan_testkit::fuzzing::request (see that function for what it checks).
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| riskplan_testkit::fuzzing::request(data));
