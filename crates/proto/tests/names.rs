//! PLC ids, verbs, topics, broker URLs and the small name sets.

use std::net::SocketAddr;

use cetratus_proto::{
    command_body, command_from_body, parse_topic, parse_verb, BrokerUrl, Command, ErrorCode, Leaf,
    PlcId, ProtoError, Reply, Sample, SignalMask, SignalValue, Slot, Status, SubstituteArgs,
    SubstituteMode, Topics, Verb, Verdict, VerdictKind, VerdictResult, ALL_PLCS_FILTER,
};
use serde_json::{json, Value};

// ------------------------------------------------------------------------------ PLC ids

#[test]
fn plc_ids_follow_the_one_rule_of_the_plc_and_the_dashboard() {
    for good in [
        "cell1",
        "press-7",
        "a.b_c",
        "Zelle ü",
        "x".repeat(256).as_str(),
    ] {
        let id = PlcId::new(good).expect(good);
        assert_eq!(id.as_str(), good);
        assert!(PlcId::is_valid(good));
    }
    for (bad, why) in [
        ("", "empty"),
        ("a/b", "`/`"),
        ("a+b", "wildcard"),
        ("a#", "wildcard"),
        ("a\nb", "control character"),
        ("a\u{7f}", "control character"),
        (&"x".repeat(257), "longer than 256 bytes"),
    ] {
        let e = PlcId::new(bad).expect_err(bad).to_string();
        assert!(e.contains(why), "{bad:?}: {e}");
        assert!(e.contains("e.g. `cell1`"), "says what to do: {e}");
        assert!(!PlcId::is_valid(bad));
    }
    // The id is shown escaped, so a control character cannot garble a terminal.
    let e = PlcId::new("a\nb").expect_err("control").to_string();
    assert!(e.contains(r"a\nb"), "{e}");
}

#[test]
fn plc_ids_are_checked_when_deserialised() {
    let id: PlcId = serde_json::from_value(json!("cell1")).expect("valid");
    assert_eq!(id.to_string(), "cell1");
    assert!(serde_json::from_value::<PlcId>(json!("a/b")).is_err());
    assert_eq!(serde_json::to_value(&id).expect("ser"), json!("cell1"));
}

// ------------------------------------------------------------------------------ verbs

#[test]
fn verbs_are_todays_strings() {
    let names: Vec<&str> = Verb::ALL.iter().map(|v| v.as_str()).collect();
    assert_eq!(
        names,
        [
            "load",
            "remove",
            "substitute",
            "abort",
            "reset",
            "exec_info",
            "revert",
            "accept"
        ]
    );
    let t = Topics::new(PlcId::new("c").expect("id"));
    for &v in Verb::ALL {
        assert_eq!(v.as_str().parse::<Verb>().expect("parses"), v);
        assert_eq!(v.to_string(), v.as_str());
        assert_eq!(Leaf::Cmd(v).as_str(), format!("cmd/{v}"));
        assert_eq!(t.cmd(v), format!("cetratus/c/cmd/{v}"));
        assert_eq!(serde_json::to_value(v).expect("ser"), json!(v.as_str()));
    }
    assert!(Verb::Load.takes_arguments() && !Verb::Abort.takes_arguments());
}

#[test]
fn an_unknown_verb_lists_the_known_ones() {
    for bad in ["explode", "Load", "exec-info", ""] {
        let e = parse_verb(bad).expect_err(bad);
        assert!(matches!(&e, ProtoError::UnknownVerb(v) if v == bad));
        let list = Verb::ALL
            .iter()
            .map(|v| v.as_str())
            .collect::<Vec<_>>()
            .join(", ");
        assert_eq!(
            e.to_string(),
            format!("unknown verb `{bad}`; expected one of {list}"),
            "the message the PLC has always sent"
        );
    }
}

// ------------------------------------------------------------------------------ topics

#[test]
fn topics_are_built_once_and_parse_back() {
    let t = Topics::new(PlcId::new("cell1").expect("id"));
    assert_eq!(t.prefix(), "cetratus/cell1/");
    assert_eq!(t.state(), "cetratus/cell1/state");
    assert_eq!(t.exec_info(), "cetratus/cell1/exec_info");
    assert_eq!(t.io(), "cetratus/cell1/io");
    assert_eq!(t.net(), "cetratus/cell1/net");
    assert_eq!(t.events(), "cetratus/cell1/events");
    assert_eq!(t.command_filter(), "cetratus/cell1/cmd/+");
    assert_eq!(t.all_filter(), "cetratus/cell1/#");
    assert_eq!(ALL_PLCS_FILTER, "cetratus/+/#");
    let mut leaves: Vec<Leaf> = Leaf::PUBLISHED.to_vec();
    leaves.extend(Verb::ALL.iter().map(|&v| Leaf::Cmd(v)));
    for leaf in leaves {
        let topic = t.leaf(leaf);
        assert_eq!(topic, format!("cetratus/cell1/{leaf}"));
        let (plc, back) = parse_topic(topic).expect(topic);
        assert_eq!((plc.as_str(), back), ("cell1", leaf));
        assert_eq!(t.parse(topic).expect(topic), leaf);
        assert_eq!(leaf.as_str().parse::<Leaf>().expect("leaf"), leaf);
    }
    assert_eq!(t.cmd(Verb::ExecInfo), "cetratus/cell1/cmd/exec_info");
    assert!(Leaf::State.retained() && Leaf::Net.retained() && !Leaf::Io.retained());
}

#[test]
fn foreign_topics_are_refused_and_an_unknown_verb_is_told_apart() {
    let t = Topics::new(PlcId::new("cell1").expect("id"));
    assert!(matches!(
        parse_topic("cetratus/cell1/cmd/explode"),
        Err(ProtoError::UnknownVerb(v)) if v == "explode"
    ));
    for bad in [
        "other/cell1/state",
        "cetratus/state",
        "cetratus/cell1/state/extra",
        "cetratus//state",
        "cetratus/cell1/reply/cli-7",
        "cetratusx/cell1/state",
    ] {
        assert!(
            matches!(parse_topic(bad), Err(ProtoError::Topic { .. })),
            "{bad}"
        );
    }
    assert!(t.parse("cetratus/cell2/state").is_err());
    assert_eq!(t.strip("cetratus/cell1/reply/cli-7"), Some("reply/cli-7"));
    assert_eq!(t.strip("cetratus/cell2/state"), None);
}

// ------------------------------------------------------------------------------ broker URLs

/// A URL, and the host, port, TLS and credentials it must give.
type UrlCase<'a> = (&'a str, &'a str, u16, bool, Option<(&'a str, &'a str)>);

fn url(s: &str) -> BrokerUrl {
    BrokerUrl::parse(s).unwrap_or_else(|e| panic!("{s}: {e}"))
}

#[test]
fn every_documented_and_tested_broker_url_form_is_accepted() {
    let cases: &[UrlCase] = &[
        ("mqtt://127.0.0.1:1883", "127.0.0.1", 1883, false, None),
        ("mqtt://127.0.0.1:1884", "127.0.0.1", 1884, false, None),
        ("mqtt://broker", "broker", 1883, false, None),
        (
            "mqtt://plant-broker:1883",
            "plant-broker",
            1883,
            false,
            None,
        ),
        ("mqtt://broker/", "broker", 1883, false, None),
        ("tcp://broker:1999", "broker", 1999, false, None),
        ("MQTT://Broker:1", "Broker", 1, false, None),
        ("mqtts://plant.example", "plant.example", 8883, true, None),
        ("mqtts://plant:8883", "plant", 8883, true, None),
        ("ssl://plant:9000", "plant", 9000, true, None),
        ("mqtt://[::1]:1999", "::1", 1999, false, None),
        ("mqtt://[::1]", "::1", 1883, false, None),
        (
            "mqtt://op:pw@10.0.0.5:1999",
            "10.0.0.5",
            1999,
            false,
            Some(("op", "pw")),
        ),
        (
            "mqtt://alice:s3cret@plant:1883/",
            "plant",
            1883,
            false,
            Some(("alice", "s3cret")),
        ),
        (
            "mqtt://alice@plant",
            "plant",
            1883,
            false,
            Some(("alice", "")),
        ),
        (
            "mqtt://a%40b:p%3Aw%40@h",
            "h",
            1883,
            false,
            Some(("a@b", "p:w@")),
        ),
    ];
    for (s, host, port, tls, creds) in cases {
        let u = url(s);
        assert_eq!(u.host(), *host, "{s}");
        assert_eq!(u.port(), *port, "{s}");
        assert_eq!(u.tls(), *tls, "{s}");
        assert_eq!(u.credentials(), *creds, "{s}");
        assert_eq!(s.parse::<BrokerUrl>().expect("FromStr"), u);
    }
}

#[test]
fn a_broker_url_displays_without_credentials() {
    assert_eq!(
        url("mqtt://alice:s3cret@plant:1883/").to_string(),
        "mqtt://plant:1883"
    );
    assert_eq!(url("mqtt://[::1]:1999").to_string(), "mqtt://[::1]:1999");
    assert_eq!(url("ssl://h").to_string(), "mqtts://h:8883");
    assert_eq!(url("tcp://h").host_port(), "h:1883");
    let debug = format!("{:?}", url("mqtt://a:s3cret@h"));
    assert!(!debug.contains("s3cret"), "{debug}");
}

#[test]
fn the_embedded_brokers_address_is_a_broker_url() {
    let a: SocketAddr = "127.0.0.1:1884".parse().expect("addr");
    let u = BrokerUrl::from_socket_addr(a);
    assert_eq!(u.to_string(), "mqtt://127.0.0.1:1884");
    assert_eq!(url(&u.to_string()), u);
    let a: SocketAddr = "[::1]:1883".parse().expect("addr");
    assert_eq!(
        BrokerUrl::from_socket_addr(a).to_string(),
        "mqtt://[::1]:1883"
    );
}

#[test]
fn configured_credentials_override_the_urls() {
    let u = url("mqtt://a:b@h").with_credentials(Some("ops"), Some("pw"));
    assert_eq!(u.credentials(), Some(("ops", "pw")));
    let u = url("mqtt://a:b@h").with_credentials(None, Some("pw"));
    assert_eq!(u.credentials(), Some(("a", "pw")));
    let u = url("mqtt://a:b@h").with_credentials(Some("ops"), None);
    assert_eq!(u.credentials(), Some(("ops", "b")));
    let u = url("mqtt://h").with_credentials(None, Some("pw"));
    assert_eq!(u.credentials(), None);
    let u = url("mqtt://h").with_credentials(Some("ops"), None);
    assert_eq!(u.credentials(), Some(("ops", "")));
}

#[test]
fn unusable_broker_urls_say_what_is_wrong_and_what_to_write() {
    let cases = [
        ("127.0.0.1:1883", "no scheme; write `mqtt://127.0.0.1:1883`"),
        ("localhost:1883", "no scheme; write `mqtt://localhost:1883`"),
        ("broker", "no scheme"),
        ("", "empty"),
        ("http://h", "unknown scheme `http`"),
        ("ws://h:9001", "unknown scheme `ws`"),
        ("mqtt://:1883", "host"),
        ("mqtt://", "host"),
        ("mqtt://h:port", "invalid port"),
        ("mqtt://h:70000", "invalid port"),
        ("mqtt://h:0", "from 1 to 65535"),
        ("mqtt://h/topic", "no path"),
        ("mqtt://h?x=1", "no path, query"),
        ("mqtt://h#f", "fragment"),
    ];
    for (bad, why) in cases {
        let e = BrokerUrl::parse(bad).expect_err(bad).to_string();
        assert!(e.contains(why), "{bad}: {e}");
        assert!(e.contains(&format!("`{bad}`")), "names the URL: {e}");
        assert!(e.contains("expected mqtt://host:port"), "{e}");
    }
}

#[test]
fn a_refused_url_does_not_print_its_password() {
    let e = BrokerUrl::parse("http://alice:s3cret@h")
        .expect_err("scheme")
        .to_string();
    assert!(!e.contains("s3cret"), "{e}");
    assert!(e.contains("alice:***@h"), "{e}");
    let e = BrokerUrl::parse("alice:s3cret@h:1883")
        .expect_err("no scheme")
        .to_string();
    assert!(!e.contains("s3cret"), "{e}");
}

// ------------------------------------------------------------------------------ names and values

#[test]
fn name_sets_read_and_write_their_wire_strings() {
    assert_eq!(
        Status::ALL.iter().map(|s| s.as_str()).collect::<Vec<_>>(),
        ["idle", "setup", "quarantine", "probation", "fault"]
    );
    for s in Status::ALL {
        assert_eq!(serde_json::to_value(s).expect("ser"), json!(s.as_str()));
        assert_eq!(s.as_str().parse::<Status>().expect("parses"), *s);
    }
    assert_eq!(serde_json::to_value(Slot::B).expect("ser"), json!("B"));
    assert_eq!(Slot::A.other(), Slot::B);
    assert_eq!(Slot::B.index(), 1);
    assert!("a".parse::<Slot>().is_err(), "the wire says A or B");
    let e = "busy!"
        .parse::<ErrorCode>()
        .expect_err("unknown")
        .to_string();
    assert!(e.contains("not_allowed"), "{e}");
    for c in ErrorCode::ALL {
        assert_eq!(serde_json::to_value(c).expect("ser"), json!(c.as_str()));
    }
    assert_eq!(SubstituteMode::Keep.to_string(), "keep");
}

#[test]
fn signal_values_keep_their_json_types() {
    for (v, j) in [
        (SignalValue::Bool(true), json!(true)),
        (SignalValue::Int(-3), json!(-3)),
        (SignalValue::Int(5), json!(5)),
        (SignalValue::Real(2.5), json!(2.5)),
        (SignalValue::Real(1.0), json!(1.0)),
    ] {
        assert_eq!(serde_json::to_value(v).expect("ser"), j);
        assert_eq!(serde_json::from_value::<SignalValue>(j).expect("de"), v);
    }
    // An integer stays an integer and a real a real, byte for byte.
    assert_eq!(
        serde_json::to_string(&SignalValue::Real(1.0)).expect("ser"),
        "1.0"
    );
    // JSON has no NaN: it goes out as null (as serde_json::Value did) and comes back as NaN.
    assert_eq!(
        serde_json::to_value(SignalValue::Real(f64::NAN)).expect("ser"),
        Value::Null
    );
    assert!(
        matches!(serde_json::from_value::<SignalValue>(Value::Null), Ok(SignalValue::Real(x)) if x.is_nan())
    );
    assert!(serde_json::from_value::<SignalValue>(json!("on")).is_err());
    assert!(serde_json::from_value::<SignalValue>(json!(u64::MAX)).is_err());
}

#[test]
fn a_sample_is_a_seven_element_array() {
    let s = Sample {
        time_ms: 105840,
        primary: Slot::A,
        status: Status::Idle,
        inputs: 5.into(),
        outputs_a: Some(2.into()),
        outputs_b: None,
        dispatched: 2.into(),
    };
    let j = json!([105840, "A", "idle", 5, 2, null, 2]);
    assert_eq!(serde_json::to_value(&s).expect("ser"), j);
    assert_eq!(serde_json::from_value::<Sample>(j).expect("de"), s);
    assert!(serde_json::from_value::<Sample>(json!([1, "A", "idle", 5, 2, null])).is_err());
}

#[test]
fn a_mask_past_bit_52_is_an_array_of_32_bit_words() {
    // Signals 0, 53 and 199 of a 200-signal program: JavaScript cannot hold bit 53 in a number.
    let m = SignalMask::from_u64_words(&[1 | 1 << 53, 0, 0, 1 << (199 - 192)]);
    let j = serde_json::to_value(&m).expect("ser");
    assert_eq!(j, json!([1, 1 << 21, 0, 0, 0, 0, 1 << 7]));
    let back: SignalMask = serde_json::from_value(j).expect("de");
    assert!(back.get(0) && back.get(53) && back.get(199) && !back.get(198));
    // Below bit 53 it stays the number it always was.
    assert_eq!(
        serde_json::to_value(SignalMask::from(1u64 << 52)).expect("ser"),
        json!(1u64 << 52)
    );
    for bad in [
        json!(1u64 << 53),
        json!([1, -1]),
        json!("3"),
        json!(vec![0; 129]),
    ] {
        let e = serde_json::from_value::<SignalMask>(bad.clone()).expect_err("refused");
        assert!(e.to_string().contains("signal mask"), "{bad}: {e}");
    }
}

#[test]
fn a_verdict_reads_and_writes() {
    let j =
        json!({"kind": "twin", "result": "warn", "reasons": ["slow"], "figures": {"drift": 2.0}});
    let v: Verdict = serde_json::from_value(j.clone()).expect("de");
    assert_eq!(v.kind, VerdictKind::Twin);
    assert_eq!(v.result, VerdictResult::Warn);
    assert_eq!(serde_json::to_value(&v).expect("ser"), j);
    assert!(serde_json::from_value::<Verdict>(
        json!({"kind": "oracle", "result": "pass", "reasons": [], "figures": {}})
    )
    .is_err());
}

#[test]
fn replies_and_commands_build_as_the_plc_and_the_cli_do() {
    let r =
        Reply::err("load", 9, ErrorCode::Malformed, "bad").with_correlation(Some(json!("abc-7")));
    assert_eq!(
        serde_json::to_string(&r).expect("ser"),
        r#"{"correlation":"abc-7","error":{"code":"malformed","message":"bad"},"ok":false,"request_id":9,"verb":"load"}"#
    );
    let r = Reply::ok("abort", 3, Some(json!({"accepted": true})));
    assert_eq!(
        serde_json::to_string(&r).expect("ser"),
        r#"{"ok":true,"request_id":3,"result":{"accepted":true},"verb":"abort"}"#
    );
    let c = Command::Substitute(SubstituteArgs {
        mode: Some(SubstituteMode::Keep),
        ..SubstituteArgs::default()
    });
    assert_eq!(
        command_body(&c).to_string(),
        r#"{"force":false,"mode":"keep","when":null,"within_ms":null}"#
    );
    assert_eq!(command_body(&Command::Reset), json!({}));
    assert_eq!(
        command_from_body(Verb::Substitute, json!({})).expect("all optional"),
        Command::Substitute(SubstituteArgs::default())
    );
    assert!(command_from_body(Verb::Substitute, json!({"mode": "yolo"})).is_err());
    assert!(command_from_body(Verb::Load, json!({})).is_err());
    let mut body =
        json!({"mode": "keep", "reply_to": "ops/r", "correlation": null, "envelope": {"k": 1}});
    let obj = body.as_object_mut().expect("object");
    let (fields, env) = cetratus_proto::ReplyFields::split(obj);
    assert_eq!(fields.reply_to.as_deref(), Some("ops/r"));
    assert_eq!(fields.correlation, Some(Value::Null));
    assert_eq!(env, Some(json!({"k": 1})));
    assert_eq!(body, json!({"mode": "keep"}));
}
