//! Compiles our minimal Waymo `.proto` with protox (pure Rust, no system `protoc`) and prost.
fn main() {
    let proto = "proto/waymo_minimal.proto";
    println!("cargo:rerun-if-changed={proto}");
    let fds = protox::compile([proto], ["proto"]).expect("proto/waymo_minimal.proto must compile");
    prost_build::Config::new().compile_fds(fds).expect("prost code generation for waymo_minimal.proto");
}
