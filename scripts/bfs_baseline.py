#!/usr/bin/env python3
"""Plain-Python breadth-first reachability: the baseline of the `reachability_states_per_s` figure.

The straightforward program an engineer would write: markings are tuples, the visited set is a
Python set, the queue a deque, every enabled transition is one edge. No packing, no tricks.

    python3 scripts/bfs_baseline.py --family kanban --n 4
    python3 scripts/bfs_baseline.py --family fms --n 4
    python3 scripts/bfs_baseline.py --pnml path/to/net.pnml

Prints `states edges seconds` on its last line (seconds: the search only, not the set-up).
Capacities and inhibitor arcs are not supported by the PNML reader here (plain P/T nets only).
"""

import argparse
import sys
import time
import xml.etree.ElementTree as ET
from collections import deque


def fms(n):
    places = [("P1d", 0), ("P1s", 0), ("P1wP2", 0), ("P12", 0), ("P1", n), ("P1wM1", 0),
              ("P1M1", 0), ("M1", 3), ("P2wM2", 0), ("P2", n), ("M2", 1), ("P2M2", 0),
              ("P12M3", 0), ("P12wM3", 0), ("P12s", 0), ("M3", 2), ("P3s", 0), ("P3M2", 0),
              ("P2wP1", 0), ("P2d", 0), ("P3", n), ("P2s", 0)]
    transitions = [
        (["M1", "P1wM1"], ["P1M1"]), (["P1"], ["P1wM1"]), (["P12wM3", "M3"], ["P12M3"]),
        (["P12M3"], ["P12s", "M3"]), (["P2wP1", "P1wP2"], ["P12"]), (["P12"], ["P12wM3"]),
        (["P1s"], ["P1"]), (["P1d"], ["P1wP2"]), (["P1M1"], ["P1d", "M1"]), (["P1d"], ["P1s"]),
        (["P2s"], ["P2"]), (["P3"], ["P3M2"]), (["P2d"], ["P2wP1"]), (["P2d"], ["P2s"]),
        (["P2wM2", "M2"], ["P2M2"]), (["P2M2"], ["P2d", "M2"]), (["P12s"], ["P2", "P1"]),
        (["P2"], ["P2wM2"]), (["P3s"], ["P3"]), (["P3M2", "M2"], ["M2", "P3s"])]
    return places, [([(p, 1) for p in i], [(p, 1) for p in o]) for i, o in transitions]


def kanban(n):
    places = []
    for c in "1234":
        places += [("Pm" + c, 0), ("Pback" + c, 0), ("Pout" + c, 0), ("P" + c, n)]
    transitions = [(["P1"], ["Pm1"])]
    for c in "1234":
        transitions += [(["Pm" + c], ["Pback" + c]), (["Pm" + c], ["Pout" + c]),
                        (["Pback" + c], ["Pm" + c])]
    transitions += [(["Pout1", "P2", "P3"], ["P1", "Pm2", "Pm3"]),
                    (["Pout2", "Pout3", "P4"], ["P2", "P3", "Pm4"]),
                    (["Pout4"], ["P4"])]
    return places, [([(p, 1) for p in i], [(p, 1) for p in o]) for i, o in transitions]


def local(tag):
    return tag.rsplit("}", 1)[-1]


def number(text):
    # PIPE 5 writes "Default,3"; the others a plain integer.
    text = (text or "").strip()
    if not text:
        return 1
    return int(text.split(",")[-1])


def read_pnml(path):
    """Plain P/T nets in the ISO or PIPE dialect (pages flattened, no reference nodes)."""
    root = ET.parse(path).getroot()
    places, trans, arcs = [], [], []
    for el in root.iter():
        tag = local(el.tag)
        if tag == "place":
            m = 0
            for c in el:
                if local(c.tag) == "initialMarking":
                    t = c.find(".//{*}text")
                    v = c.find(".//{*}value")
                    raw = t.text if t is not None else (v.text if v is not None else "0")
                    m = number(raw) if (raw or "").strip() else 0
            places.append((el.get("id"), m))
        elif tag == "transition":
            trans.append(el.get("id"))
        elif tag == "arc":
            w = 1
            for c in el:
                if local(c.tag) == "inscription":
                    t = c.find(".//{*}text")
                    v = c.find(".//{*}value")
                    raw = t.text if t is not None else (v.text if v is not None else "")
                    w = number(raw)
            arcs.append((el.get("source"), el.get("target"), w))
    tindex = {t: i for i, t in enumerate(trans)}
    ts = [([], []) for _ in trans]
    for s, t, w in arcs:
        if t in tindex:
            ts[tindex[t]][0].append((s, w))
        else:
            ts[tindex[s]][1].append((t, w))
    return places, ts


def bfs(places, transitions):
    index = {p: i for i, (p, _) in enumerate(places)}
    compiled = []
    for ins, outs in transitions:
        pre = [(index[p], w) for p, w in ins]
        delta = {}
        for p, w in ins:
            delta[index[p]] = delta.get(index[p], 0) - w
        for p, w in outs:
            delta[index[p]] = delta.get(index[p], 0) + w
        compiled.append((pre, list(delta.items())))
    m0 = tuple(m for _, m in places)
    seen = {m0}
    queue = deque([m0])
    edges = 0
    while queue:
        m = queue.popleft()
        for pre, delta in compiled:
            if all(m[p] >= w for p, w in pre):
                edges += 1
                s = list(m)
                for p, d in delta:
                    s[p] += d
                s = tuple(s)
                if s not in seen:
                    seen.add(s)
                    queue.append(s)
    return len(seen), edges


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--family", choices=["kanban", "fms"])
    ap.add_argument("--n", type=int, default=2)
    ap.add_argument("--pnml")
    a = ap.parse_args()
    if a.pnml:
        places, transitions = read_pnml(a.pnml)
    elif a.family == "kanban":
        places, transitions = kanban(a.n)
    elif a.family == "fms":
        places, transitions = fms(a.n)
    else:
        ap.error("give --family or --pnml")
    start = time.perf_counter()
    states, edges = bfs(places, transitions)
    seconds = time.perf_counter() - start
    print(f"{states} {edges} {seconds:.6f}")


if __name__ == "__main__":
    sys.exit(main())
