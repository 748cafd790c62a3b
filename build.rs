//! Links the `gema2` binary at a fixed address (not as a position-independent executable) on
//! Linux. Every stage of a pipeline is a process of this one binary. A PIE's relocated data
//! (about 450 KB of `.data.rel.ro`: vtables, panic locations, string tables) is written at load
//! in each process and so is private to each; linked at a fixed address it stays clean pages of
//! the file that all the stages share. Shared libraries, heap, stacks and the shared-memory
//! segments stay at random addresses. `GEMA2_PIE=1` at build time links a PIE instead, for a
//! deployment that would rather have the code at random addresses too (the `ros2` stage reads
//! the network). See docs/design.md, "Memory of a stage".

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=GEMA2_PIE");
    let pie = std::env::var_os("GEMA2_PIE").is_some_and(|v| v != "0" && !v.is_empty());
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") && !pie {
        println!("cargo:rustc-link-arg-bin=gema2=-no-pie");
    }
}
