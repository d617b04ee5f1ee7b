//! With the `mpi` feature: generates the Rust declarations of the PETSc functions
//! `distributed::petsc` calls (bindgen on `petscksp.h`) and links PETSc. Without it: nothing.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    #[cfg(feature = "mpi")]
    petsc::generate();
}

#[cfg(feature = "mpi")]
mod petsc {
    use std::path::PathBuf;
    use std::process::Command;

    /// Where Debian's `libpetsc-real-dev` puts PETSc; `PETSC_DIR` overrides it.
    const DEBIAN_PETSC_DIR: &str = "/usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real";

    /// Flags `pkg-config` prints for `package`, if it knows it.
    fn pkg_config(package: &str, flag: &str) -> Option<Vec<String>> {
        let out = Command::new("pkg-config")
            .args([flag, package])
            .output()
            .ok()?;
        out.status.success().then(|| {
            String::from_utf8_lossy(&out.stdout)
                .split_whitespace()
                .map(str::to_owned)
                .collect()
        })
    }

    pub fn generate() {
        println!("cargo:rerun-if-env-changed=PETSC_DIR");
        let petsc_dir = std::env::var("PETSC_DIR").unwrap_or_else(|_| DEBIAN_PETSC_DIR.into());
        let include = format!("{petsc_dir}/include");
        if !std::path::Path::new(&include).join("petscksp.h").exists() {
            panic!(
                "the `mpi` feature needs PETSc: {include}/petscksp.h not found \
                 (run `make mpi`, which installs libpetsc-real-dev, or set PETSC_DIR)"
            );
        }
        println!("cargo:rustc-link-search=native={petsc_dir}/lib");
        println!("cargo:rustc-link-lib=dylib=petsc_real");
        // PT-Scotch (PETSc's partitioner here), for seeding its random generator.
        println!("cargo:rustc-link-lib=dylib=ptscotch-7.0");
        let mpi_includes = pkg_config("ompi-c", "--cflags-only-I")
            .or_else(|| pkg_config("mpi", "--cflags-only-I"))
            .unwrap_or_else(|| vec!["-I/usr/lib/x86_64-linux-gnu/openmpi/include".into()]);
        let bindings = bindgen::Builder::default()
            .header_contents("petsc_wrapper.h", "#include <petscksp.h>\n")
            .clang_arg(format!("-I{include}"))
            .clang_args(mpi_includes)
            .allowlist_function("Petsc(Initialize|InitializeNoArguments|Finalize|Initialized|OptionsHasName|OptionsSetValue)")
            .allowlist_function("Vec(CreateMPI|SetBlockSize|GetLocalSize|SetValues|AssemblyBegin|AssemblyEnd|GetArray|RestoreArray|GetArrayRead|RestoreArrayRead|Destroy|Duplicate|Set|CreateSeq|ScatterCreate|ScatterBegin|ScatterEnd|ScatterDestroy|GetOwnershipRange|Norm)")
            .allowlist_function("Mat(Create|SetSizes|SetType|SetBlockSize|SeqAIJSetPreallocation|MPIAIJSetPreallocation|SetValues|AssemblyBegin|AssemblyEnd|ZeroEntries|SetOption|SetNearNullSpace|NullSpaceCreateRigidBody|NullSpaceDestroy|Destroy|GetInfo|CreateMPIAdj|GetInertia)")
            .allowlist_function("KSP(SetOptionsPrefix|Create|SetOperators|SetType|GetPC|SetTolerances|SetFromOptions|SetUp|Solve|GetIterationNumber|GetConvergedReason|Destroy|SetReusePreconditioner|SetInitialGuessNonzero)")
            .allowlist_function("PC(SetType|GAMGSetNSmooths|SetFromOptions|FactorGetMatrix|RedundantGetKSP)")
            .allowlist_function("IS(CreateGeneral|Destroy|GetIndices|RestoreIndices|GetLocalSize)")
            .allowlist_function("MatPartitioning(Create|SetAdjacency|SetType|Apply|Destroy)")
            .allowlist_function("PetscMallocA")
            .allowlist_var("PETSC_COMM_WORLD")
            .allowlist_type("(PetscBool|PetscCopyMode|InsertMode|ScatterMode|MatAssemblyType|MatOption|KSPConvergedReason|NormType|MatInfoType)")
            .default_enum_style(bindgen::EnumVariation::Rust { non_exhaustive: false })
            .generate()
            .expect("bindgen could not read petscksp.h");
        let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
        bindings
            .write_to_file(out.join("petsc_bindings.rs"))
            .expect("writing the PETSc bindings");
    }
}
