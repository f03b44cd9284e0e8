//! Head-on blocks through augury contact: rebound speed and closest gap per contact model and
//! transfer, against the look-ahead τ and under refinement, and the damping of a lone vibrating
//! block, and against the impact speed (the figures quoted in `docs/augury.md`).
//!
//! `cargo run --release -p femp-augury --example blocks` (`ONLY=speed`: only the last table,
//! the impact speed).

use femp_augury::scenes::{
    BlocksContact, HeadOnSetup, head_on_blocks, head_on_blocks_with, vibrating_block,
};
use femp_augury::{ContactModel, TransferKind};

fn main() {
    if std::env::var("ONLY").as_deref() == Ok("speed") {
        impact_speed();
        return;
    }
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
        let timing = HeadOnSetup {
            dt_fraction,
            tau_over_dt: tau / dt_fraction,
            duration: 1.0,
            ..HeadOnSetup::default()
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
    // Refinement: mesh and grid together (grid = 2 × mesh size), τ = Δt = half the stable step.
    println!(
        "\nunder refinement, τ = Δt = Δt_s / 2, 2 s (relative speed at the end / closest gap in grid cells / time within one cell):"
    );
    for cells in [8, 16, 32, 64] {
        let setup = HeadOnSetup {
            cells,
            duration: 2.0,
            ..HeadOnSetup::default()
        };
        let cell = 2.0 / cells as f64;
        for kind in [TransferKind::Apic, TransferKind::Pic] {
            for model in &models[..3] {
                match head_on_blocks_with(BlocksContact::Augury(*model, kind), 0.0, &setup) {
                    Ok(r) => println!(
                        "{cells} × {cells}, {model:?} {kind:?}: {:+.3} m/s, {:.3} cells, {:.3} s",
                        r.separation_speed,
                        r.min_gap / cell,
                        r.contact_time
                    ),
                    Err(e) => println!("{cells} × {cells}, {model:?} {kind:?}: {e}"),
                }
            }
        }
    }
    // Self-damping: a lone block in its lowest compression mode, τ = Δt = Δt_s / 20, 0.5 s.
    println!("\na lone vibrating block, τ = Δt = Δt_s / 20: energy left after 0.5 s");
    for cells in [8, 16, 32] {
        let setup = HeadOnSetup {
            cells,
            dt_fraction: 0.05,
            tau_over_dt: 1.0,
            duration: 0.5,
            ..HeadOnSetup::default()
        };
        for (label, contact) in [
            ("no contact", None),
            ("APIC", Some((ContactModel::Sticky, TransferKind::Apic))),
            ("PIC", Some((ContactModel::Sticky, TransferKind::Pic))),
        ] {
            match vibrating_block(contact, &setup) {
                Ok(r) => println!(
                    "{cells} × {cells}, {label}: {:.3}",
                    r.energy.last().map_or(f64::NAN, |e| e.1)
                ),
                Err(e) => println!("{cells} × {cells}, {label}: {e}"),
            }
        }
    }
    impact_speed();
}

/// Impact speed: the 3D scene's blocks meet at ≈ 16 % of the dilatational wave speed each,
/// these at 2.7 % (1 m/s of 36.7); the same 32 × 32 blocks faster, run to 1 s after contact.
fn impact_speed() {
    println!(
        "\nimpact speed, 32 × 32, τ = Δt = Δt_s / 2 (relative speed at the end / approach, closest gap in grid cells, time within one cell):"
    );
    for speed in [1.0, 2.5, 6.0] {
        let setup = HeadOnSetup {
            cells: 32,
            duration: 0.5 / speed + 1.0,
            speed,
            ..HeadOnSetup::default()
        };
        let cell = 2.0 / 32.0;
        for model in [ContactModel::Sticky, ContactModel::Separation] {
            match head_on_blocks_with(
                BlocksContact::Augury(model, TransferKind::Apic),
                0.0,
                &setup,
            ) {
                Ok(r) => println!(
                    "{speed} m/s each ({:.1} % of c_p), {model:?}: {:+.3}, {:.3} cells, {:.3} s",
                    100.0 * speed / 36.7,
                    r.separation_speed / (2.0 * speed),
                    r.min_gap / cell,
                    r.contact_time
                ),
                Err(e) => println!("{speed} m/s, {model:?}: {e}"),
            }
        }
    }
}
