//! Write the benchmark matrices as Matrix Market files (symmetric, lower triangle) for the
//! CHOLMOD comparison: `cargo run --release -p femp-solver --example write_matrices -- DIR`.

#[path = "../benches/common/matrices.rs"]
mod matrices;

fn main() -> std::io::Result<()> {
    let dir =
        std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "matrices".into()));
    std::fs::create_dir_all(&dir)?;
    for case in matrices::all() {
        let path = dir.join(format!("{}.mtx", case.name));
        matrices::write_mtx(&case, &path)?;
        println!(
            "{}: n = {}, nnz = {}",
            path.display(),
            case.csc.n(),
            case.csc.nnz()
        );
    }
    Ok(())
}
