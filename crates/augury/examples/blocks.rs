//! Head-on blocks through augury contact: rebound speed and closest gap per contact model and
//! transfer (the figures quoted in `docs/augury.md`).
//!
//! `cargo run --release -p femp-augury --example blocks`

use femp_augury::scenes::{BlocksContact, head_on_blocks};
use femp_augury::{ContactModel, TransferKind};

fn main() {
    match head_on_blocks(BlocksContact::Penalty, 0.0) {
        Ok(r) => println!(
            "penalty baseline: relative speed at 0.8 s {:+.3} m/s (approach −2), closest gap {:.4} m, momentum drift {:.1e}",
            r.separation_speed, r.min_gap, r.max_p_error
        ),
        Err(e) => println!("penalty baseline: {e}"),
    }
    for model in [
        ContactModel::Sticky,
        ContactModel::Separation,
        ContactModel::Friction(0.0),
        ContactModel::Friction(0.3),
    ] {
        for kind in [TransferKind::Apic, TransferKind::Pic] {
            match head_on_blocks(BlocksContact::Augury(model, kind), 0.0) {
                Ok(r) => println!(
                    "{model:?} {kind:?}: relative speed at 0.8 s {:+.3} m/s (approach −2), closest gap {:.3} m, momentum drift {:.1e}",
                    r.separation_speed, r.min_gap, r.max_p_error
                ),
                Err(e) => println!("{model:?} {kind:?}: {e}"),
            }
        }
    }
}
