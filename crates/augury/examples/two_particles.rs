//! Two equal particles approaching each other on a background grid, interacting only through
//! the augury correction: where do they come to rest? Prints the final gap (in cells) for APIC
//! and PIC, both kernels, several τ v0 / h (§3.1 as a simulation; see
//! `femp_augury::two_particle::simulate`).
//!
//! `cargo run --release -p femp-augury --example two_particles`

use femp_augury::TransferKind;
use femp_augury::two_particle::simulate;
use femp_kernels::Kernel;

fn main() {
    for kernel in [Kernel::Quadratic, Kernel::Quadratic4] {
        for kind in [TransferKind::Apic, TransferKind::Pic] {
            for tau in [0.01, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0] {
                match simulate(kernel, kind, tau, 200_000) {
                    Ok(m) => println!(
                        "{kernel:?} {kind:?} τv0/h = {tau}: gap {:+.4} cells, speed {:.2e}, {} steps",
                        m.gap_cells, m.speed, m.steps
                    ),
                    Err(e) => println!("{kernel:?} {kind:?} τv0/h = {tau}: {e}"),
                }
            }
        }
    }
}
