#!/usr/bin/env python3
"""A real Modbus TCP peer for the tests, on pymodbus.

  modbus_peer.py device PORT [--unit U] [--di 1,0,1] [--co 1,0] [--size N] [--delay-ms MS]
      a remote I/O device: discrete inputs and coils as given, input and holding registers;
      reads past `size` entries get an exception; every answer waits `delay-ms`.
  modbus_peer.py read PORT TABLE ADDRESS COUNT [--unit U]
      prints the values read, comma-separated (TABLE: coils, di, ir, hr).
  modbus_peer.py write PORT TABLE ADDRESS VALUE [--unit U]
      writes one coil (0/1) or holding register; prints `ok` or the exception.
  modbus_peer.py flood PORT N
      opens N connections at once and holds them for a second; prints how many were accepted.
  modbus_peer.py session PORT OP... [--source IP]
      one client connection (from IP, when given) that runs each OP in turn and prints one line
      for each: `read:TABLE:ADDRESS:COUNT` prints the values, `write:TABLE:ADDRESS:VALUE`
      prints `ok`, `wait:TABLE:ADDRESS:VALUE` reads until the value is there (30 s at most) and
      prints `ok` or `timeout LAST`, `unit:U` addresses unit U from then on, and
      `raw:FUNCTION:ADDRESS:COUNT` sends a read frame that pymodbus would refuse to send (on a
      connection of its own) and prints `ok` or the exception. A refused request prints
      `exception CODE`.
"""
import argparse
import asyncio
import logging
import socket
import sys
import time

logging.getLogger("pymodbus").setLevel(logging.ERROR)


def device(args):
    from pymodbus.datastore import (ModbusDeviceContext, ModbusSequentialDataBlock,
                                    ModbusServerContext)
    from pymodbus.server import StartAsyncTcpServer

    di = [v == "1" for v in args.di.split(",")] if args.di else []
    di += [False] * (args.size - len(di))
    co = [v == "1" for v in args.co.split(",")] if args.co else []
    co += [False] * (args.size - len(co))
    ctx = ModbusDeviceContext(
        di=ModbusSequentialDataBlock(1, di[: args.size]),
        co=ModbusSequentialDataBlock(1, co[: args.size]),
        ir=ModbusSequentialDataBlock(1, [0] * args.size),
        hr=ModbusSequentialDataBlock(1, [0] * args.size),
    )
    server = ModbusServerContext(devices={args.unit: ctx}, single=False)

    async def main():
        kwargs = {}
        if args.delay_ms:
            delay = args.delay_ms / 1000

            def trace_pdu(sending, pdu):
                if sending:
                    time.sleep(delay)
                return pdu

            kwargs["trace_pdu"] = trace_pdu
        print("ready", flush=True)
        await StartAsyncTcpServer(server, address=("127.0.0.1", args.port), **kwargs)

    asyncio.run(main())


def client(args):
    from pymodbus.client import ModbusTcpClient

    source = getattr(args, "source", None)
    c = ModbusTcpClient("127.0.0.1", port=args.port, timeout=5,
                        source_address=(source, 0) if source else None)
    if not c.connect():
        print("cannot connect", file=sys.stderr)
        sys.exit(2)
    return c


def read(args):
    c = client(args)
    fn = {"coils": c.read_coils, "di": c.read_discrete_inputs,
          "ir": c.read_input_registers, "hr": c.read_holding_registers}[args.table]
    r = fn(args.address, count=args.count, device_id=args.unit)
    if r.isError():
        print(f"exception {r}")
        sys.exit(1)
    vals = r.bits[: args.count] if args.table in ("coils", "di") else r.registers
    print(",".join(str(int(v)) for v in vals))


def write(args):
    c = client(args)
    if args.table == "coils":
        r = c.write_coil(args.address, bool(args.value), device_id=args.unit)
    else:
        r = c.write_register(args.address, args.value, device_id=args.unit)
    print(f"exception {r}" if r.isError() else "ok")


def flood(args):
    socks = []
    for _ in range(args.n):
        try:
            socks.append(socket.create_connection(("127.0.0.1", args.port), timeout=1))
        except OSError:
            pass
    time.sleep(1)
    print(len(socks))


def session(args):
    c = client(args)
    unit = 1

    def read_one(table, address, count):
        fn = {"coils": c.read_coils, "di": c.read_discrete_inputs,
              "ir": c.read_input_registers, "hr": c.read_holding_registers}[table]
        try:
            r = fn(address, count=count, device_id=unit)
        except Exception as e:  # a closed connection, a timeout
            return f"error {type(e).__name__}"
        if r.isError():
            return f"exception {getattr(r, 'exception_code', r)}"
        vals = r.bits[:count] if table in ("coils", "di") else r.registers
        return ",".join(str(int(v)) for v in vals)

    for op in args.ops:
        kind, *rest = op.split(":")
        if kind == "unit":
            unit = int(rest[0])
            print("ok", flush=True)
        elif kind == "read":
            print(read_one(rest[0], int(rest[1]), int(rest[2])), flush=True)
        elif kind == "write":
            table, address, value = rest[0], int(rest[1]), int(rest[2])
            try:
                if table == "coils":
                    r = c.write_coil(address, bool(value), device_id=unit)
                else:
                    r = c.write_register(address, value, device_id=unit)
                print(f"exception {getattr(r, 'exception_code', r)}" if r.isError() else "ok",
                      flush=True)
            except Exception as e:
                print(f"error {type(e).__name__}", flush=True)
        elif kind == "raw":
            fc, address, count = int(rest[0]), int(rest[1]), int(rest[2])
            with socket.create_connection(("127.0.0.1", args.port), timeout=5) as raw:
                pdu = bytes([fc]) + address.to_bytes(2, "big") + count.to_bytes(2, "big")
                raw.sendall((1).to_bytes(2, "big") + b"\0\0" + (len(pdu) + 1).to_bytes(2, "big")
                            + bytes([unit]) + pdu)
                answer = raw.recv(300)
            if len(answer) >= 9 and answer[7] == fc | 0x80:
                print(f"exception {answer[8]}", flush=True)
            else:
                print("ok" if len(answer) > 8 else "error no answer", flush=True)
        elif kind == "wait":
            table, address, value = rest[0], int(rest[1]), rest[2]
            end = time.monotonic() + 30
            last = read_one(table, address, 1)
            while last != value and time.monotonic() < end:
                time.sleep(0.02)
                last = read_one(table, address, 1)
            print("ok" if last == value else f"timeout {last}", flush=True)
        else:
            print(f"unknown op {op}", flush=True)


p = argparse.ArgumentParser()
sub = p.add_subparsers(dest="cmd", required=True)
d = sub.add_parser("device")
d.add_argument("port", type=int)
d.add_argument("--unit", type=int, default=1)
d.add_argument("--di", default="")
d.add_argument("--co", default="")
d.add_argument("--size", type=int, default=64)
d.add_argument("--delay-ms", type=int, default=0)
for name in ("read", "write"):
    r = sub.add_parser(name)
    r.add_argument("port", type=int)
    r.add_argument("table", choices=["coils", "di", "ir", "hr"])
    r.add_argument("address", type=int)
    r.add_argument("count" if name == "read" else "value", type=int)
    r.add_argument("--unit", type=int, default=1)
f = sub.add_parser("flood")
f.add_argument("port", type=int)
f.add_argument("n", type=int)
s = sub.add_parser("session")
s.add_argument("port", type=int)
s.add_argument("ops", nargs="+")
s.add_argument("--source")
a = p.parse_args()
{"device": device, "read": read, "write": write, "flood": flood, "session": session}[a.cmd](a)
