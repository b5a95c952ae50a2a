//! Unit tests of the Festo station's physics: strokes, faults, defects and the reject bin.

use super::input::*;
use super::output::*;
use super::*;
use crate::Plant;

/// Steps to `t_ms` with the listed outputs on, returns the input image.
fn drive(st: &mut FestoStation, t_ms: u64, on: &[usize]) -> [bool; 15] {
    let mut outs = [false; 8];
    for &o in on {
        outs[o] = true;
    }
    st.step(t_ms * 1_000, &outs);
    let mut ins = [false; 15];
    st.inputs(&mut ins);
    ins
}

fn kinds(st: &FestoStation) -> Vec<FaultKind> {
    st.faults().iter().map(|f| f.kind).collect()
}

/// Indexes the table once, stopping on the cam; starts and ends at `t_ms`.
fn index(st: &mut FestoStation, t_ms: &mut u64) {
    let mut left = false;
    loop {
        *t_ms += 10;
        let i = drive(st, *t_ms, &[TABLE_MOTOR]);
        if !i[TABLE_IN_POS] {
            left = true;
        } else if left {
            break;
        }
    }
    *t_ms += 10;
    drive(st, *t_ms, &[]);
}

#[test]
fn the_first_part_is_placed_at_the_input_at_once() {
    let mut st = FestoStation::with_defaults(0);
    let i = drive(&mut st, 0, &[]);
    assert!(i[PART_AT_INPUT] && i[TABLE_IN_POS] && i[DRILL_UP]);
    assert_eq!(st.counters().get("parts_supplied"), Some(1));
}

#[test]
fn one_index_takes_one_second_and_moves_the_part_to_the_tester() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[]);
    let mut t = 0;
    index(&mut st, &mut t);
    assert_eq!(
        t, 1_020,
        "motor on at 10 ms, in position at 1 010 ms, off 10 ms later"
    );
    let i = drive(&mut st, t + 10, &[]);
    assert!(i[PART_AT_TEST] && i[TABLE_IN_POS] && !i[PART_AT_INPUT]);
}

#[test]
fn a_table_left_running_passes_the_position() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[TABLE_MOTOR]);
    assert!(drive(&mut st, 1_050, &[TABLE_MOTOR])[TABLE_IN_POS]);
    assert!(!drive(&mut st, 1_150, &[TABLE_MOTOR])[TABLE_IN_POS]);
}

#[test]
fn turning_the_table_with_the_tester_down_is_a_fault() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[TESTER_SOLENOID]);
    drive(&mut st, 600, &[TESTER_SOLENOID]);
    drive(&mut st, 610, &[TESTER_SOLENOID, TABLE_MOTOR]);
    drive(&mut st, 620, &[TESTER_SOLENOID, TABLE_MOTOR]);
    assert_eq!(kinds(&st), vec![FaultKind::TableTurnWhileEngaged]);
    assert_eq!(
        st.faults()[0].message,
        "the table turned while the tester was down"
    );
}

#[test]
fn turning_the_table_before_the_drill_is_up_is_a_fault() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[DRILL_FEED_DOWN]);
    drive(&mut st, 500, &[]);
    drive(&mut st, 510, &[TABLE_MOTOR]);
    assert_eq!(kinds(&st), vec![FaultKind::TableTurnWhileEngaged]);
}

#[test]
fn drilling_without_clamp_is_a_fault_and_leaves_the_part_undrilled() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[]);
    let mut t = 0;
    index(&mut st, &mut t);
    index(&mut st, &mut t);
    assert!(drive(&mut st, t, &[])[PART_AT_DRILL]);
    drive(&mut st, t + 10, &[DRILL_MOTOR, DRILL_FEED_DOWN]);
    let i = drive(&mut st, t + 2_010, &[DRILL_MOTOR, DRILL_FEED_DOWN]);
    assert!(i[DRILL_DOWN]);
    assert_eq!(kinds(&st), vec![FaultKind::DrillWithoutClamp]);
    assert_eq!(st.counters().get("parts_drilled"), Some(0));
}

#[test]
fn drilling_with_the_spindle_stopped_is_a_fault() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[]);
    let mut t = 0;
    index(&mut st, &mut t);
    index(&mut st, &mut t);
    drive(&mut st, t, &[CLAMP]);
    drive(&mut st, t + 300, &[CLAMP, DRILL_FEED_DOWN]);
    drive(&mut st, t + 2_300, &[CLAMP, DRILL_FEED_DOWN]);
    assert_eq!(kinds(&st), vec![FaultKind::DrillMotorOff]);
}

#[test]
fn opening_the_clamp_with_the_drill_in_the_part_is_a_fault() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[]);
    let mut t = 0;
    index(&mut st, &mut t);
    index(&mut st, &mut t);
    drive(&mut st, t, &[CLAMP]);
    drive(&mut st, t + 300, &[CLAMP, DRILL_MOTOR, DRILL_FEED_DOWN]);
    drive(&mut st, t + 1_000, &[DRILL_MOTOR, DRILL_FEED_DOWN]);
    assert_eq!(kinds(&st), vec![FaultKind::DrillWithoutClamp]);
}

#[test]
fn engaging_a_module_between_positions_is_a_fault() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[TABLE_MOTOR]);
    drive(&mut st, 500, &[]);
    drive(&mut st, 510, &[EJECTOR]);
    assert_eq!(kinds(&st), vec![FaultKind::EngagedOutOfPosition]);
}

#[test]
fn the_drill_feed_goes_down_in_two_seconds_and_up_in_half_a_second() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[DRILL_FEED_DOWN]);
    assert!(!drive(&mut st, 1_999, &[DRILL_FEED_DOWN])[DRILL_DOWN]);
    let i = drive(&mut st, 2_000, &[]);
    assert!(i[DRILL_DOWN] && !i[DRILL_UP]);
    assert!(!drive(&mut st, 2_499, &[])[DRILL_UP]);
    assert!(drive(&mut st, 2_500, &[])[DRILL_UP]);
}

#[test]
fn a_pressed_button_is_held_for_the_press_time() {
    let mut st = FestoStation::with_defaults(0);
    st.press("start", 1_000_000)
        .expect("the station has a start button");
    assert!(!drive(&mut st, 990, &[])[START]);
    assert!(drive(&mut st, 1_000, &[])[START]);
    assert!(drive(&mut st, 1_190, &[])[START]);
    assert!(!drive(&mut st, 1_200, &[])[START]);
    assert!(st.press("emergency", 0).is_err());
}

#[test]
fn parts_wait_upstream_while_the_input_nest_is_full() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 10_000, &[]);
    let c = st.counters();
    assert_eq!(c.get("parts_supplied"), Some(1));
    assert_eq!(c.get("parts_waiting"), Some(2));
}

/// A station whose every part is defective, with a part under the tester at `t_ms`.
fn defective_part_under_the_tester(t_ms: &mut u64) -> FestoStation {
    let params = FestoParams {
        defect_ppm: PPM,
        ..FestoParams::default()
    };
    let mut st = FestoStation::new(params, 0).expect("valid parameters");
    drive(&mut st, 0, &[]);
    index(&mut st, t_ms);
    assert!(drive(&mut st, *t_ms, &[])[PART_AT_TEST]);
    st
}

#[test]
fn the_probe_stops_on_a_defective_part_and_the_test_never_passes() {
    let mut t = 0;
    let mut st = defective_part_under_the_tester(&mut t);
    let i = drive(&mut st, t + 10, &[TESTER_SOLENOID]);
    assert!(!i[TESTER_DOWN] && !i[TEST_OK]);
    let i = drive(&mut st, t + 3_000, &[TESTER_SOLENOID]);
    assert!(
        !i[TESTER_DOWN] && !i[TEST_OK],
        "the probe rests on the part"
    );
    assert_eq!(st.counters().get("parts_tested"), Some(1));
    assert_eq!(st.counters().get("parts_defective"), Some(1));
}

#[test]
fn a_good_part_passes_the_test_and_keeps_its_result_after_the_probe_lifts() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[]);
    let mut t = 0;
    index(&mut st, &mut t);
    drive(&mut st, t, &[TESTER_SOLENOID]);
    let i = drive(&mut st, t + 500, &[TESTER_SOLENOID]);
    assert!(i[TESTER_DOWN] && i[TEST_OK]);
    let i = drive(&mut st, t + 510, &[]);
    assert!(!i[TESTER_DOWN] && i[TEST_OK]);
}

#[test]
fn the_rejector_pushes_the_part_under_the_tester_into_the_reject_bin() {
    let mut t = 0;
    let mut st = defective_part_under_the_tester(&mut t);
    drive(&mut st, t + 10, &[TESTER_SOLENOID]);
    drive(&mut st, t + 1_010, &[REJECTOR]);
    assert!(!drive(&mut st, t + 1_500, &[REJECTOR])[REJECTOR_OUT]);
    let i = drive(&mut st, t + 1_510, &[REJECTOR]);
    assert!(i[REJECTOR_OUT] && !i[PART_AT_TEST]);
    let c = st.counters();
    assert_eq!(c.get("parts_rejected"), Some(1));
    assert_eq!(c.get("parts_rejected_good"), Some(0));
    assert!(st.faults().is_empty(), "faults: {:?}", st.faults());
}

#[test]
fn rejecting_with_the_probe_down_is_a_fault_and_the_part_stays() {
    let mut t = 0;
    let mut st = defective_part_under_the_tester(&mut t);
    drive(&mut st, t + 10, &[TESTER_SOLENOID]);
    drive(&mut st, t + 1_010, &[TESTER_SOLENOID, REJECTOR]);
    let i = drive(&mut st, t + 1_600, &[TESTER_SOLENOID, REJECTOR]);
    assert!(i[PART_AT_TEST]);
    assert_eq!(kinds(&st), vec![FaultKind::RejectUnderProbe]);
}

#[test]
fn turning_the_table_with_the_rejector_out_is_a_fault() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[REJECTOR]);
    drive(&mut st, 600, &[REJECTOR, TABLE_MOTOR]);
    assert_eq!(kinds(&st), vec![FaultKind::TableTurnWhileEngaged]);
}

#[test]
fn a_defect_share_over_one_million_parts_per_million_is_refused() {
    let params = FestoParams {
        defect_ppm: PPM + 1,
        ..FestoParams::default()
    };
    assert!(matches!(
        FestoStation::new(params, 0),
        Err(TwinError::InvalidParameter {
            name: "defect_ppm",
            ..
        })
    ));
}

#[test]
fn a_part_is_drilled_when_the_drill_bottoms_out_as_the_next_part_arrives() {
    let mut st = FestoStation::with_defaults(0);
    drive(&mut st, 0, &[]);
    let mut t = 0;
    index(&mut st, &mut t);
    index(&mut st, &mut t);
    assert!(t < 2_800 && drive(&mut st, t, &[])[PART_AT_DRILL]);
    drive(&mut st, 2_800, &[CLAMP]);
    // Fed from 3 s, the drill reaches the bottom at 5 s, when the second part arrives.
    drive(&mut st, 3_000, &[CLAMP, DRILL_MOTOR, DRILL_FEED_DOWN]);
    drive(&mut st, 5_010, &[CLAMP, DRILL_MOTOR, DRILL_FEED_DOWN]);
    assert_eq!(st.counters().get("parts_drilled"), Some(1));
}

#[test]
fn invalid_parameters_are_rejected_with_the_parameter_named() {
    let params = FestoParams {
        in_position_window_us: 2 * SECOND_US,
        ..FestoParams::default()
    };
    match FestoStation::new(params, 0) {
        Err(TwinError::InvalidParameter { name, .. }) => {
            assert_eq!(name, "in_position_window_us")
        }
        other => panic!("expected an invalid parameter, got {other:?}"),
    }
}
