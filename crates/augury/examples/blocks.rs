//! Head-on blocks through augury contact: rebound speed and closest gap per contact model and
//! transfer, then the same against the look-ahead τ (the figures quoted in `docs/augury.md`).
//!
//! `cargo run --release -p femp-augury --example blocks`

use femp_augury::scenes::{BlocksContact, HeadOnTiming, head_on_blocks, head_on_blocks_with};
use femp_augury::{ContactModel, TransferKind};

fn main() {
    match head_on_blocks(BlocksContact::Penalty, 0.0) {
        Ok(r) => println!(
            "penalty baseline: relative speed at 0.8 s {:+.3} m/s (approach −2), closest gap {:.4} m, momentum drift {:.1e}",
            r.separation_speed, r.min_gap, r.max_p_error
        ),
        Err(e) => println!("penalty baseline: {e}"),
    }
    let models = [
        ContactModel::Sticky,
        ContactModel::Separation,
        ContactModel::Friction(0.0),
        ContactModel::Friction(0.3),
    ];
    for model in models {
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
    // The look-ahead τ, in units of the explicit stability estimate Δt_s; Δt = min(τ, Δt_s/2).
    println!(
        "\nagainst τ (grid spacing 0.25 m; relative speed at 1 s / closest gap / gap at 1 s):"
    );
    for tau in [0.5, 0.05, 0.01] {
        let dt_fraction = f64::min(tau, 0.5);
        let timing = HeadOnTiming {
            dt_fraction,
            tau_over_dt: tau / dt_fraction,
            duration: 1.0,
        };
        for model in &models[..3] {
            for kind in [TransferKind::Apic, TransferKind::Pic] {
                match head_on_blocks_with(BlocksContact::Augury(*model, kind), 0.0, &timing) {
                    Ok(r) => println!(
                        "τ = {tau} Δt_s, {model:?} {kind:?}: {:+.3} m/s, {:.3} m, {:.3} m",
                        r.separation_speed, r.min_gap, r.final_gap
                    ),
                    Err(e) => println!("τ = {tau} Δt_s, {model:?} {kind:?}: {e}"),
                }
            }
        }
    }
}
