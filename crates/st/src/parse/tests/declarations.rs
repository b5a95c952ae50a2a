//! Declarations: types, POUs and variables, configurations.

#![allow(unused_imports)]
use super::*;

#[test]
fn the_sample_program_is_read_whole() {
    let l = lib(SAMPLE);
    assert_eq!(l.types.len(), 3);
    assert_eq!(l.pous.len(), 3);
    assert_eq!(l.configs.len(), 1);
}

// ---- Types ----

#[test]
fn a_struct_type_with_initial_values_is_read() {
    let l = lib("TYPE P : STRUCT a, b : INT := 1; s : STRING(8); END_STRUCT; END_TYPE");
    let TypeDeclKind::Struct(members) = &l.types[0].kind else {
        panic!("not a struct")
    };
    assert_eq!(members.len(), 2);
    assert_eq!(members[0].names.len(), 2);
    assert!(matches!(members[0].init, Some(Init::Expr(_))));
    assert!(matches!(
        &members[1].ty,
        TypeRef::String { len: Some(_), .. }
    ));
}

#[test]
fn an_enum_with_explicit_values_and_an_initial_value_is_read() {
    let l = lib("TYPE Color : (Red := 1, Green, Blue := -3) := Green; END_TYPE");
    let TypeDeclKind::Enum { values, init } = &l.types[0].kind else {
        panic!("not an enum")
    };
    assert_eq!(values.len(), 3);
    assert!(values[0].1.is_some() && values[1].1.is_none());
    assert_eq!(init.as_ref().map(|i| i.text.as_str()), Some("Green"));
}

#[test]
fn an_enum_with_a_base_type_is_read_in_both_vendors_spellings() {
    for text in [
        "TYPE E : (A, B) INT; END_TYPE",
        "TYPE E : INT (A := 1, B := 2) := B; END_TYPE",
        "TYPE E : DINT (A); END_TYPE",
    ] {
        assert!(
            matches!(lib(text).types[0].kind, TypeDeclKind::Enum { .. }),
            "{text}"
        );
    }
}

#[test]
fn an_alias_a_subrange_and_an_array_type_are_read() {
    let l = lib(
        "TYPE Speed : INT := 10; Level : INT (0..100) := 5; Grid : ARRAY [1..3, 0..1] OF INT := [1, 2, 3(0)]; END_TYPE",
    );
    assert!(matches!(
        &l.types[0].kind,
        TypeDeclKind::Alias {
            range: None,
            init: Some(_),
            ..
        }
    ));
    assert!(matches!(
        &l.types[1].kind,
        TypeDeclKind::Alias {
            range: Some(_),
            init: Some(_),
            ..
        }
    ));
    let TypeDeclKind::Alias {
        ty: TypeRef::Array { dims, .. },
        init: Some(Init::Array(elems, _)),
        ..
    } = &l.types[2].kind
    else {
        panic!("not an array alias")
    };
    assert_eq!(dims.len(), 2);
    assert_eq!(elems.len(), 3);
    assert!(elems[2].0.is_some());
}

#[test]
fn the_semicolon_before_end_type_may_be_left_out() {
    let l = lib("TYPE P :\nSTRUCT\n  a : INT;\nEND_STRUCT\nEND_TYPE\nTYPE A : INT END_TYPE");
    assert_eq!(l.types.len(), 2);
}

#[test]
fn two_type_declarations_need_a_semicolon_between_them() {
    let d = lib_err("TYPE A : INT B : INT; END_TYPE");
    assert_eq!(
        d.message,
        "expected ';' after the type declaration, found 'B'"
    );
}

// ---- POUs and variables ----

#[test]
fn a_function_a_function_block_and_a_program_are_read() {
    let l = lib(
        "FUNCTION F : STRING[10] F := 'x'; END_FUNCTION FUNCTION_BLOCK B END_FUNCTION_BLOCK PROGRAM P ; END_PROGRAM",
    );
    assert!(matches!(
        &l.pous[0].kind,
        PouKind::Function(TypeRef::String { len: Some(_), .. })
    ));
    assert!(matches!(l.pous[1].kind, PouKind::FunctionBlock));
    assert!(l.pous[1].body.is_empty());
    assert!(matches!(l.pous[2].kind, PouKind::Program));
    assert!(matches!(l.pous[2].body[0].kind, StmtKind::Empty));
}

#[test]
fn var_blocks_of_every_section_with_their_qualifiers_are_read() {
    let l = lib("PROGRAM P
         VAR a : INT; END_VAR
         VAR_INPUT b : INT; END_VAR
         VAR_OUTPUT c : INT; END_VAR
         VAR_IN_OUT d : INT; END_VAR
         VAR_TEMP e : INT; END_VAR
         VAR_EXTERNAL f : INT; END_VAR
         VAR_GLOBAL g : INT; END_VAR
         VAR CONSTANT k : INT := 1; END_VAR
         VAR RETAIN r : INT; END_VAR
         VAR PERSISTENT pr : INT; END_VAR
         VAR NON_RETAIN nr : INT; END_VAR
         END_PROGRAM");
    let blocks = &l.pous[0].vars;
    let sections: Vec<Section> = blocks.iter().map(|b| b.section).collect();
    assert_eq!(
        &sections[..7],
        &[
            Section::Var,
            Section::Input,
            Section::Output,
            Section::InOut,
            Section::Temp,
            Section::External,
            Section::Global
        ]
    );
    assert!(blocks[7].constant && !blocks[7].retain);
    assert!(blocks[8].retain && blocks[9].retain && !blocks[10].retain);
}

#[test]
fn retain_and_non_retain_together_are_refused() {
    let d = lib_err("PROGRAM P VAR RETAIN NON_RETAIN a : INT; END_VAR END_PROGRAM");
    assert!(
        d.message.contains("RETAIN or NON_RETAIN, not both"),
        "{}",
        d.message
    );
}

#[test]
fn declarations_with_addresses_strings_arrays_and_initial_values_are_read() {
    let l = lib("PROGRAM P VAR
           a, b AT %IX0.0 : BOOL := TRUE;
           x AT %QW1 : INT;
           s : STRING[20] := 'abc';
           s2 : STRING(20);
           s3 : STRING;
           m : ARRAY [1..3, 0..1] OF INT := [1, 2, 3(0)];
           n : ARRAY [1..2] OF ARRAY [1..2] OF INT := [[1, 2], [3, 4]];
           p : Pair := (a := 1, b := [1.0, 2.0, 3.0]);
         END_VAR END_PROGRAM");
    let decls = &l.pous[0].vars[0].decls;
    assert_eq!(decls[0].names.len(), 2);
    assert_eq!(
        decls[0].at.as_ref().map(|a| a.text.as_str()),
        Some("%IX0.0")
    );
    assert_eq!(decls[1].at.as_ref().map(|a| a.text.as_str()), Some("%QW1"));
    assert!(matches!(decls[4].ty, TypeRef::String { len: None, .. }));
    let Some(Init::Array(elems, _)) = &decls[5].init else {
        panic!("not an array init")
    };
    let (Some(count), Init::Expr(zero)) = &elems[2] else {
        panic!("not a repeated element")
    };
    assert_eq!(
        (show(count), show(zero)),
        ("3".to_string(), "0".to_string())
    );
    assert!(
        matches!(&decls[6].ty, TypeRef::Array { elem, .. } if matches!(**elem, TypeRef::Array { .. }))
    );
    let Some(Init::Struct(members, _)) = &decls[7].init else {
        panic!("not a struct init")
    };
    assert!(matches!(members[1].1, Init::Array(..)));
}

#[test]
fn a_function_block_instance_with_input_values_is_read() {
    let l = lib("PROGRAM P VAR t : TON := (PT := T#1s); END_VAR END_PROGRAM");
    let Some(Init::Struct(members, _)) = &l.pous[0].vars[0].decls[0].init else {
        panic!("not an instance init")
    };
    assert_eq!(members[0].0.text, "PT");
}

#[test]
fn a_function_without_a_return_type_is_refused() {
    let d = lib_err("FUNCTION F VAR_INPUT x : INT; END_VAR END_FUNCTION");
    assert_eq!(
        d.message,
        "expected ':' and the return type after the FUNCTION's name, found 'VAR_INPUT'"
    );
}

#[test]
fn the_end_keyword_must_match_the_pou() {
    let d = lib_err("PROGRAM Main x := 1; END_FUNCTION_BLOCK");
    assert_eq!(
        d.message,
        "expected END_PROGRAM to close PROGRAM Main, found 'END_FUNCTION_BLOCK'"
    );
}

#[test]
fn a_subrange_in_a_variable_declaration_is_refused_with_the_way_to_declare_it() {
    let d = lib_err("PROGRAM P VAR x : INT (0..10); END_VAR END_PROGRAM");
    assert!(
        d.message.contains("TYPE Level : INT (0..100)"),
        "{}",
        d.message
    );
}

#[test]
fn an_anonymous_enumeration_in_a_declaration_is_refused() {
    let d = lib_err("PROGRAM P VAR x : (A, B); END_VAR END_PROGRAM");
    assert!(d
        .message
        .starts_with("an enumeration must be declared as a type"));
}

// ---- Configurations ----

#[test]
fn a_configuration_with_a_resource_tasks_and_programs_is_read() {
    let l = lib("CONFIGURATION C
           VAR_GLOBAL g : INT := 3; END_VAR
           RESOURCE R ON PLC
             VAR_GLOBAL h AT %QX0.0 : BOOL; END_VAR
             TASK Fast (INTERVAL := T#20ms, PRIORITY := 1);
             TASK Slow (PRIORITY := 2);
             PROGRAM A WITH Fast : Main;
             PROGRAM B : Other;
           END_RESOURCE
         END_CONFIGURATION");
    let c = &l.configs[0];
    assert_eq!(c.tasks.len(), 2);
    assert_eq!(
        c.tasks[0].interval.as_ref().map(show),
        Some("20000000ns".into())
    );
    assert!(c.tasks[1].interval.is_none());
    assert_eq!(
        c.programs[0].task.as_ref().map(|t| t.text.as_str()),
        Some("Fast")
    );
    assert_eq!(c.programs[1].program.text, "Other");
    assert!(c.programs[1].task.is_none());
    assert_eq!(c.globals.len(), 2);
}

#[test]
fn a_configuration_without_a_resource_is_read() {
    let l =
        lib("CONFIGURATION C TASK T (INTERVAL := T#1s); PROGRAM I WITH T : P; END_CONFIGURATION");
    assert_eq!(l.configs[0].tasks.len(), 1);
    assert_eq!(l.configs[0].programs.len(), 1);
}

#[test]
fn an_event_task_is_refused() {
    let d = lib_err("CONFIGURATION C TASK T (SINGLE := trig); END_CONFIGURATION");
    assert!(d
        .message
        .starts_with("event tasks (SINGLE) are not supported"));
}

#[test]
fn var_global_outside_a_configuration_is_refused() {
    let d = lib_err("VAR_GLOBAL g : INT; END_VAR");
    assert!(d
        .message
        .starts_with("VAR_GLOBAL outside a CONFIGURATION is not supported"));
}
