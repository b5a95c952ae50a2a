#!/usr/bin/env python3
"""A real OPC UA client for the tests, on asyncua (FreeOpcUa's Python stack).

  opcua_peer.py browse URL
      prints the string id of every node under the Cetratus PLC object, one per line, sorted
      (the PLC object itself first).
  opcua_peer.py read URL ID...
      prints `ID=VALUE` per node (a bad status prints its name).
  opcua_peer.py write URL ID TYPE VALUE
      writes VALUE as TYPE (bool, int16, int32, int64, double, float, string); prints `ok` or
      the status name of the refusal.
  opcua_peer.py subscribe URL ID SECONDS
      subscribes to the node (publishing interval 50 ms) and prints how many distinct values
      it was told of in that time, then the last one.
  opcua_peer.py events URL SECONDS [--source]
      subscribes to the Server object's events, prints `subscribed`, and after SECONDS the event
      type of each one received (with --source, and the string id of its source node).
  opcua_peer.py wait URL ID VALUE SECONDS
      reads the node until it shows VALUE; prints `ok` or `timeout LAST`.
  opcua_peer.py run URL SCRIPT...
      one session that runs each step in turn, a line each: `w:ID:TYPE:VALUE`, `r:ID`,
      `wait:ID:VALUE` (30 s at most), `keep:ID:TYPE:VALUE:SECONDS` (writes the value every
      50 ms for SECONDS, as a client's keep-alive; prints `ok` or the first refusal).
  opcua_peer.py secure URL POLICY CERT KEY [--user U --password P]
      connects with POLICY (Basic256Sha256, Aes128_Sha256_RsaOaep, Aes256_Sha256_RsaPss) and
      Sign & Encrypt, with the client certificate CERT (DER) and key KEY (PEM); prints the PLC's
      STATUS (or the node --read ID), or `refused: REASON`.
  opcua_peer.py guess URL POLICY CERT KEY USER PASSWORD N
      N logins as USER with PASSWORD over 8 encrypted connections at once, each session trying
      to activate again after each refusal; prints how many ended how (`ok=…`, the name of each
      refusal with its count), sorted.
  opcua_peer.py junk URL N
      one session that writes N malformed values (wrong types, unknown nodes, an index range),
      then reads STATUS; prints each status name with its count, sorted, then STATUS.
  opcua_peer.py keys DIR
      writes a self-signed client certificate (DIR/client.der) and key (DIR/client.pem).
  opcua_peer.py sessions URL N
      opens N sessions at once and holds them; prints how many the server let in, then the
      refusal of the others.
  opcua_peer.py flood URL N
      opens N TCP connections at once, holds them two seconds, and prints how many the server
      closed at once.
"""
import argparse
import asyncio
import logging
import socket
import sys
import time

logging.getLogger("asyncua").setLevel(logging.CRITICAL)

from asyncua import Client, ua  # noqa: E402

NAMESPACE = "urn:cetratus"
TYPES = {
    "bool": (lambda v: v in ("1", "true", "True"), ua.VariantType.Boolean),
    "int16": (int, ua.VariantType.Int16),
    "int32": (int, ua.VariantType.Int32),
    "int64": (int, ua.VariantType.Int64),
    "double": (float, ua.VariantType.Double),
    "float": (float, ua.VariantType.Float),
    "string": (str, ua.VariantType.String),
}


async def node_of(client, ident):
    ns = await client.get_namespace_index(NAMESPACE)
    return client.get_node(ua.NodeId(ident, ns))


def show(v):
    if isinstance(v, bool):
        return "1" if v else "0"
    return str(v)


async def read_one(client, ident):
    try:
        return show(await (await node_of(client, ident)).read_value())
    except ua.UaStatusCodeError as e:
        return type(e).__name__


async def write_one(client, ident, ty, value):
    conv, vt = TYPES[ty]
    node = await node_of(client, ident)
    try:
        await node.write_value(ua.DataValue(ua.Variant(conv(value), vt)))
        return "ok"
    except ua.UaStatusCodeError as e:
        return type(e).__name__


async def wait_for(client, ident, value, seconds):
    end = time.monotonic() + seconds
    last = None
    while time.monotonic() < end:
        last = await read_one(client, ident)
        if last == value:
            return "ok"
        await asyncio.sleep(0.02)
    return f"timeout {last}"


async def browse(url):
    async with Client(url) as c:
        ns = await c.get_namespace_index(NAMESPACE)
        objects = c.nodes.objects
        out = []
        for child in await objects.get_children():
            if child.nodeid.NamespaceIndex != ns:
                continue
            out.append(child.nodeid.Identifier)
            stack = [child]
            while stack:
                n = stack.pop()
                for k in await n.get_children():
                    if k.nodeid.NamespaceIndex == ns:
                        out.append(k.nodeid.Identifier)
                        stack.append(k)
        print(out[0])
        for i in sorted(out[1:]):
            print(i)


async def read(url, ids):
    async with Client(url) as c:
        for i in ids:
            print(f"{i}={await read_one(c, i)}")


async def write(url, ident, ty, value):
    async with Client(url) as c:
        print(await write_one(c, ident, ty, value))


class Counter:
    def __init__(self):
        self.values = []
        self.events = []

    def datachange_notification(self, node, val, data):
        self.values.append(val)

    def event_notification(self, event):
        self.events.append(event)


async def subscribe(url, ident, seconds):
    async with Client(url) as c:
        h = Counter()
        sub = await c.create_subscription(50, h)
        await sub.subscribe_data_change(await node_of(c, ident))
        await asyncio.sleep(seconds)
        distinct = len(set(map(str, h.values)))
        print(distinct)
        print(show(h.values[-1]) if h.values else "none")


async def events(url, seconds, source=False, until=None):
    """Subscribes to the Server's events, says "subscribed", and prints the events' types after
    `seconds`, or as soon as `until` (TYPE:COUNT) events of TYPE have come."""
    async with Client(url) as c:
        h = Counter()
        sub = await c.create_subscription(50, h)
        await sub.subscribe_events(c.nodes.server, queuesize=100)
        print("subscribed")
        sys.stdout.flush()
        end = asyncio.get_running_loop().time() + seconds
        kind, count = (until.rsplit(":", 1) + [None])[:2] if until else (None, None)
        while asyncio.get_running_loop().time() < end:
            if kind is not None:
                seen = sum(1 for e in h.events if e.EventType.to_string() == kind)
                if seen >= int(count):
                    break
            await asyncio.sleep(0.05)
        for e in h.events:
            if source:
                print(f"{e.EventType.to_string()} {e.SourceNode.Identifier}")
            else:
                print(e.EventType.to_string())


async def wait(url, ident, value, seconds):
    async with Client(url) as c:
        print(await wait_for(c, ident, value, seconds))


async def run(url, steps):
    async with Client(url) as c:
        for s in steps:
            parts = s.split(":")
            if parts[0] == "w":
                print(await write_one(c, parts[1], parts[2], parts[3]))
            elif parts[0] == "r":
                print(await read_one(c, parts[1]))
            elif parts[0] == "wait":
                print(await wait_for(c, parts[1], parts[2], 30))
            elif parts[0] == "keep":
                end, got = time.monotonic() + float(parts[4]), "ok"
                while time.monotonic() < end and got == "ok":
                    got = await write_one(c, parts[1], parts[2], parts[3])
                    await asyncio.sleep(0.05)
                print(got)
            sys.stdout.flush()


async def secure(url, policy, cert, key, user, password, read_id=None):
    c = Client(url)
    c.application_uri = "urn:cetratus:test-client"
    if user:
        c.set_user(user)
        c.set_password(password)
    try:
        # asyncua spells the policies without underscores (Aes128Sha256RsaOaep).
        name = policy.replace("_", "")
        await c.set_security_string(f"{name},SignAndEncrypt,{cert},{key}")
        async with c:
            ns = await c.get_namespace_index(NAMESPACE)
            objects = await c.nodes.objects.get_children()
            plc = [o for o in objects if o.nodeid.NamespaceIndex == ns][0]
            ident = read_id or f"{plc.nodeid.Identifier}.STATUS"
            print(await c.get_node(ua.NodeId(ident, ns)).read_value())
    except Exception as e:  # the refusal itself is the answer
        print(f"refused: {type(e).__name__} {e}")


async def guess(url, policy, cert, key, user, password, n):
    """8 encrypted connections, each with one session that tries to activate n/8 times."""
    counts = {}

    async def one(k):
        c = Client(url)
        c.application_uri = "urn:cetratus:test-client"
        try:
            await c.set_security_string(f"{policy.replace('_', '')},SignAndEncrypt,{cert},{key}")
            await c.connect_socket()
            await c.send_hello()
            await c.open_secure_channel()
            await c.create_session()
        except Exception as e:  # a refusal as the stack reports it
            counts[type(e).__name__] = counts.get(type(e).__name__, 0) + k
            return
        for _ in range(k):
            try:
                await c.activate_session(username=user, password=password)
                name = "ok"
            except Exception as e:  # the refusal itself is the answer
                name = type(e).__name__
            counts[name] = counts.get(name, 0) + 1
        try:
            await c.close_session()
            await c.close_secure_channel()
        except Exception:
            pass
        c.disconnect_socket()

    await asyncio.gather(*(one(n // 8 + (1 if i < n % 8 else 0)) for i in range(8)))
    print(" ".join(f"{k}={v}" for k, v in sorted(counts.items())))


async def junk(url, n):
    counts = {}
    async with Client(url) as c:
        ns = await c.get_namespace_index(NAMESPACE)
        objects = await c.nodes.objects.get_children()
        plc = [o for o in objects if o.nodeid.NamespaceIndex == ns][0].nodeid.Identifier
        cases = [
            (f"{plc}.Inputs.PE", ua.Variant(1.5, ua.VariantType.Double), None),
            (f"{plc}.Inputs.PE", ua.Variant("x" * 1000, ua.VariantType.String), None),
            (f"{plc}.Inputs.NOPE", ua.Variant(True, ua.VariantType.Boolean), None),
            ("\u00e9\u0000" * 50, ua.Variant(True, ua.VariantType.Boolean), None),
            (f"{plc}.Inputs.PE", ua.Variant([True, False], ua.VariantType.Boolean), None),
            (f"{plc}.Inputs.PE", ua.Variant(True, ua.VariantType.Boolean), "0:1"),
        ]
        for i in range(n):
            ident, v, rng = cases[i % len(cases)]
            p = ua.WriteParameters()
            wv = ua.WriteValue()
            wv.NodeId = ua.NodeId(ident, ns)
            wv.AttributeId = ua.AttributeIds.Value
            wv.Value = ua.DataValue(v)
            if rng:
                wv.IndexRange = rng
            p.NodesToWrite = [wv]
            results = await c.uaclient.write(p)
            for r in results:
                counts[r.name] = counts.get(r.name, 0) + 1
        status = await c.get_node(ua.NodeId(f"{plc}.STATUS", ns)).read_value()
    for k, v in sorted(counts.items()):
        print(f"{k}={v}")
    print(status)


def keys(directory):
    from asyncua.crypto.cert_gen import generate_private_key, generate_self_signed_app_certificate
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization
    from cryptography.x509.oid import ExtendedKeyUsageOID

    async def go():
        key = generate_private_key()
        cert = generate_self_signed_app_certificate(
            key,
            "cetratus test client",
            {"commonName": "cetratus test client"},
            [x509.UniformResourceIdentifier("urn:cetratus:test-client")],
            extended=[ExtendedKeyUsageOID.CLIENT_AUTH],
        )
        return key, cert

    key, cert = asyncio.run(go())
    # The application URI the client presents (`secure`) is the certificate's.
    with open(f"{directory}/client.der", "wb") as f:
        f.write(cert.public_bytes(serialization.Encoding.DER))
    with open(f"{directory}/client.pem", "wb") as f:
        f.write(
            key.private_bytes(
                serialization.Encoding.PEM,
                serialization.PrivateFormat.TraditionalOpenSSL,
                serialization.NoEncryption(),
            )
        )
    print("ok")


async def sessions(url, n):
    clients = [Client(url) for _ in range(n)]
    opened, refusals = [], set()
    for c in clients:
        try:
            await c.connect()
            opened.append(c)
        except Exception as e:  # the refusal itself is the answer
            refusals.add(type(e).__name__)
    print(len(opened))
    print(",".join(sorted(refusals)) or "none")
    for c in opened:
        await c.disconnect()


def flood(url, n):
    host, port = url.removeprefix("opc.tcp://").rstrip("/").rsplit(":", 1)
    socks = []
    for _ in range(n):
        s = socket.create_connection((host, int(port)), timeout=5)
        socks.append(s)
    time.sleep(0.5)
    closed = 0
    for s in socks:
        s.settimeout(1.5)
        try:
            if s.recv(1) == b"":
                closed += 1
        except (socket.timeout, ConnectionResetError):
            pass
        s.close()
    print(closed)


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("browse")
    b.add_argument("url")
    r = sub.add_parser("read")
    r.add_argument("url")
    r.add_argument("ids", nargs="+")
    w = sub.add_parser("write")
    w.add_argument("url")
    w.add_argument("id")
    w.add_argument("type", choices=sorted(TYPES))
    w.add_argument("value")
    s = sub.add_parser("subscribe")
    s.add_argument("url")
    s.add_argument("id")
    s.add_argument("seconds", type=float)
    e = sub.add_parser("events")
    e.add_argument("url")
    e.add_argument("seconds", type=float)
    e.add_argument("--source", action="store_true")
    e.add_argument("--until", help="TYPE:COUNT, stop once COUNT events of TYPE came")
    wt = sub.add_parser("wait")
    wt.add_argument("url")
    wt.add_argument("id")
    wt.add_argument("value")
    wt.add_argument("seconds", type=float)
    rn = sub.add_parser("run")
    rn.add_argument("url")
    rn.add_argument("steps", nargs="+")
    sc = sub.add_parser("secure")
    sc.add_argument("url")
    sc.add_argument("policy")
    sc.add_argument("cert")
    sc.add_argument("key")
    sc.add_argument("--user")
    sc.add_argument("--password")
    sc.add_argument("--read")
    g = sub.add_parser("guess")
    for name in ("url", "policy", "cert", "key", "user", "password"):
        g.add_argument(name)
    g.add_argument("n", type=int)
    j = sub.add_parser("junk")
    j.add_argument("url")
    j.add_argument("n", type=int)
    k = sub.add_parser("keys")
    k.add_argument("dir")
    ss = sub.add_parser("sessions")
    ss.add_argument("url")
    ss.add_argument("n", type=int)
    f = sub.add_parser("flood")
    f.add_argument("url")
    f.add_argument("n", type=int)
    a = p.parse_args()
    if a.cmd == "browse":
        asyncio.run(browse(a.url))
    elif a.cmd == "read":
        asyncio.run(read(a.url, a.ids))
    elif a.cmd == "write":
        asyncio.run(write(a.url, a.id, a.type, a.value))
    elif a.cmd == "subscribe":
        asyncio.run(subscribe(a.url, a.id, a.seconds))
    elif a.cmd == "events":
        asyncio.run(events(a.url, a.seconds, a.source, a.until))
    elif a.cmd == "wait":
        asyncio.run(wait(a.url, a.id, a.value, a.seconds))
    elif a.cmd == "run":
        asyncio.run(run(a.url, a.steps))
    elif a.cmd == "secure":
        asyncio.run(secure(a.url, a.policy, a.cert, a.key, a.user, a.password, a.read))
    elif a.cmd == "guess":
        asyncio.run(guess(a.url, a.policy, a.cert, a.key, a.user, a.password, a.n))
    elif a.cmd == "junk":
        asyncio.run(junk(a.url, a.n))
    elif a.cmd == "keys":
        keys(a.dir)
    elif a.cmd == "sessions":
        asyncio.run(sessions(a.url, a.n))
    elif a.cmd == "flood":
        flood(a.url, a.n)


if __name__ == "__main__":
    main()
