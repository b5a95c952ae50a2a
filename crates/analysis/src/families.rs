//! Generators of the classic benchmark families, built in code.
//!
//! * [`fms`]: the flexible manufacturing system of Ciardo & Trivedi as the Model Checking Contest
//!   publishes it (FMS-PT-*: 22 places, 20 transitions; N parts of each of three types, machines
//!   M1 = 3, M2 = 1, M3 = 2). Place and transition ids are the contest's.
//! * [`kanban`]: the Kanban system of Ciardo & Tilgner (16 places, 16 transitions; four cells with
//!   N kanban cards each; cell 1 feeds cells 2 and 3, which together feed cell 4).

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};

use crate::AnalysisError;

fn build(
    id: &str,
    places: &[(&str, u32)],
    transitions: &[(&str, &[&str], &[&str])],
) -> Result<Net, AnalysisError> {
    let mut b = NetBuilder::new(id);
    for &(p, m) in places {
        b.add_place(Place::new(p, m))?;
    }
    for (t, _, _) in transitions {
        b.add_transition(Transition::new(*t))?;
    }
    for (t, ins, outs) in transitions {
        for p in *ins {
            b.add_arc(&format!("{p}->{t}"), p, t, 1, ArcKind::Normal)?;
        }
        for p in *outs {
            b.add_arc(&format!("{t}->{p}"), t, p, 1, ArcKind::Normal)?;
        }
    }
    Ok(b.build()?)
}

/// The FMS net with `n` parts of each type, in the contest's declaration order.
pub fn fms(n: u32) -> Result<Net, AnalysisError> {
    let places: [(&str, u32); 22] = [
        ("P1d", 0),
        ("P1s", 0),
        ("P1wP2", 0),
        ("P12", 0),
        ("P1", n),
        ("P1wM1", 0),
        ("P1M1", 0),
        ("M1", 3),
        ("P2wM2", 0),
        ("P2", n),
        ("M2", 1),
        ("P2M2", 0),
        ("P12M3", 0),
        ("P12wM3", 0),
        ("P12s", 0),
        ("M3", 2),
        ("P3s", 0),
        ("P3M2", 0),
        ("P2wP1", 0),
        ("P2d", 0),
        ("P3", n),
        ("P2s", 0),
    ];
    let transitions: [(&str, &[&str], &[&str]); 20] = [
        ("tM1", &["M1", "P1wM1"], &["P1M1"]),
        ("tP1", &["P1"], &["P1wM1"]),
        ("tM3", &["P12wM3", "M3"], &["P12M3"]),
        ("tP12M3", &["P12M3"], &["P12s", "M3"]),
        ("tx", &["P2wP1", "P1wP2"], &["P12"]),
        ("tP12", &["P12"], &["P12wM3"]),
        ("tP1s", &["P1s"], &["P1"]),
        ("tP1j", &["P1d"], &["P1wP2"]),
        ("tP1M1", &["P1M1"], &["P1d", "M1"]),
        ("tP1e", &["P1d"], &["P1s"]),
        ("tP2s", &["P2s"], &["P2"]),
        ("tP3", &["P3"], &["P3M2"]),
        ("tP2j", &["P2d"], &["P2wP1"]),
        ("tP2e", &["P2d"], &["P2s"]),
        ("tM2", &["P2wM2", "M2"], &["P2M2"]),
        ("tP2M2", &["P2M2"], &["P2d", "M2"]),
        ("tP12s", &["P12s"], &["P2", "P1"]),
        ("tP2", &["P2"], &["P2wM2"]),
        ("tP3s", &["P3s"], &["P3"]),
        ("tP3M2", &["P3M2", "M2"], &["M2", "P3s"]),
    ];
    build(&format!("FMS-{n}"), &places, &transitions)
}

/// The Kanban net with `n` cards per cell.
pub fn kanban(n: u32) -> Result<Net, AnalysisError> {
    let mut places: Vec<(&str, u32)> = Vec::new();
    for (pm, pback, pout, p) in [
        ("Pm1", "Pback1", "Pout1", "P1"),
        ("Pm2", "Pback2", "Pout2", "P2"),
        ("Pm3", "Pback3", "Pout3", "P3"),
        ("Pm4", "Pback4", "Pout4", "P4"),
    ] {
        places.extend([(pm, 0), (pback, 0), (pout, 0), (p, n)]);
    }
    let transitions: [(&str, &[&str], &[&str]); 16] = [
        ("tin1", &["P1"], &["Pm1"]),
        ("tredo1", &["Pm1"], &["Pback1"]),
        ("tok1", &["Pm1"], &["Pout1"]),
        ("tback1", &["Pback1"], &["Pm1"]),
        ("tsynch1_23", &["Pout1", "P2", "P3"], &["P1", "Pm2", "Pm3"]),
        ("tredo2", &["Pm2"], &["Pback2"]),
        ("tok2", &["Pm2"], &["Pout2"]),
        ("tback2", &["Pback2"], &["Pm2"]),
        ("tredo3", &["Pm3"], &["Pback3"]),
        ("tok3", &["Pm3"], &["Pout3"]),
        ("tback3", &["Pback3"], &["Pm3"]),
        (
            "tsynch4_23",
            &["Pout2", "Pout3", "P4"],
            &["P2", "P3", "Pm4"],
        ),
        ("tredo4", &["Pm4"], &["Pback4"]),
        ("tok4", &["Pm4"], &["Pout4"]),
        ("tback4", &["Pback4"], &["Pm4"]),
        ("tout4", &["Pout4"], &["P4"]),
    ];
    build(&format!("Kanban-{n}"), &places, &transitions)
}
