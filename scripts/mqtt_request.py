#!/usr/bin/env python3
"""MQTT 5 request/reply against a Cetratus PLC: publish a command with a response topic and
correlation data, print the reply. Used by crates/mct tests; handy for operators too.

    python3 scripts/mqtt_request.py --port 1883 --topic cetratus/cell1/cmd/exec_info --payload '{}'

Exit status: 0 reply received with matching correlation data, 2 timeout, 3 correlation mismatch,
4 paho-mqtt missing.
"""
import argparse
import json
import sys
import threading
import uuid

try:
    import paho.mqtt.client as mqtt
    from paho.mqtt.packettypes import PacketTypes
    from paho.mqtt.properties import Properties
except ImportError:
    print("paho-mqtt is not installed: pip install paho-mqtt", file=sys.stderr)
    sys.exit(4)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=1883)
    ap.add_argument("--topic", required=True)
    ap.add_argument("--payload", default="{}")
    ap.add_argument("--username")
    ap.add_argument("--password")
    ap.add_argument("--timeout", type=float, default=10.0)
    args = ap.parse_args()

    correlation = uuid.uuid4().bytes
    # A PLC replies only under its own reply level: cetratus/<plc>/reply/...
    levels = args.topic.split("/")
    if len(levels) < 4 or levels[0] != "cetratus" or levels[2] != "cmd":
        print("--topic must be cetratus/<plc>/cmd/<verb>", file=sys.stderr)
        sys.exit(2)
    reply_topic = "cetratus/%s/reply/py-%s" % (levels[1], uuid.uuid4().hex)
    got = {}
    done = threading.Event()
    subscribed = threading.Event()

    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv5)
    if args.username:
        client.username_pw_set(args.username, args.password)

    def on_connect(c, _userdata, _flags, _reason, _props):
        c.subscribe(reply_topic, qos=1)

    def on_subscribe(_c, _userdata, _mid, _reasons, _props):
        subscribed.set()

    def on_message(_c, _userdata, msg):
        got["payload"] = msg.payload
        got["correlation"] = getattr(msg.properties, "CorrelationData", None)
        done.set()

    client.on_connect = on_connect
    client.on_subscribe = on_subscribe
    client.on_message = on_message
    client.connect(args.host, args.port)
    client.loop_start()
    if not subscribed.wait(args.timeout):
        print("timeout waiting for the subscription", file=sys.stderr)
        sys.exit(2)
    props = Properties(PacketTypes.PUBLISH)
    props.ResponseTopic = reply_topic
    props.CorrelationData = correlation
    client.publish(args.topic, args.payload.encode(), qos=1, properties=props)
    if not done.wait(args.timeout):
        print("timeout waiting for the reply", file=sys.stderr)
        sys.exit(2)
    client.loop_stop()
    client.disconnect()
    try:
        body = json.loads(got["payload"])
    except ValueError:
        body = {"raw": got["payload"].decode(errors="replace")}
    print(json.dumps({"reply": body, "correlation_matches": got["correlation"] == correlation}))
    sys.exit(0 if got["correlation"] == correlation else 3)


if __name__ == "__main__":
    main()
