//! Builds the SPIRV-Tools optimizer wrapper (`src/spirv_strip.cpp`) and links Debian's
//! static SPIRV-Tools libraries (package `spirv-tools`, installed by
//! tools/install-deps.sh, which build.rs at the root already links for shaderc), so the
//! binaries need no SPIRV-Tools at run time.

fn main() {
    println!("cargo:rerun-if-changed=src/spirv_strip.cpp");
    cc::Build::new()
        .cpp(true)
        .std("c++17")
        .file("src/spirv_strip.cpp")
        .warnings(true)
        .compile("nimbus_spirv_strip");
    println!("cargo:rustc-link-search=native=/usr/lib/x86_64-linux-gnu");
    println!("cargo:rustc-link-lib=static=SPIRV-Tools-opt");
    println!("cargo:rustc-link-lib=static=SPIRV-Tools");
    println!("cargo:rustc-link-lib=dylib=stdc++");
}
