#!/usr/bin/env python3
"""Tables of docs/perf/README.md (session 14, issue 42) from `flem bench step` JSON."""
import json, sys

d = json.load(open(sys.argv[1]))
f = lambda s: f"{s['median']:.3g} [{s['min']:.3g}-{s['max']:.3g}]"
print("triad GB/s:", {k: f(v) for k, v in d["triad_gb_per_s"].items()})
print("\n| kind | elements | crack | chunks | regions | lead | work ms | critical path us (lead + region chunks + node chunk + rest) | parallelism kernel / step | simulated step speed-up 2 / 4 / 16 / 64 (dataflow model; list) | measured step speed-up 2 [range] | measured kernel speed-up 2 [range] |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for g in d["task_graph"]:
    cp = g["critical_path"]
    sim = {s["threads"]: s for s in g["simulated_speedup"]}
    m = g["measured"]
    sp = " / ".join(f"{sim[p]['step_dataflow_model']:.1f}" for p in (2, 4, 16, 64)) + "; " + " / ".join(f"{sim[p]['step_list_schedule']:.1f}" for p in (2, 4, 16, 64))
    parts = f"{cp['seconds']*1e6:.0f} ({cp['lead_chunks']} x, {cp['lead_seconds']*1e6:.0f} + {cp['region_chunks']} x, {cp['region_seconds']*1e6:.0f} + {cp['node_seconds']*1e6:.0f} + {cp['rest_seconds']*1e6:.0f})"
    print(f"| {g['kind']} | {g['elements']:.0f} | {'yes' if g['crack'] else 'no'} | {g['chunks']} | {g['regions']} | {g['lead_chunks']} | {g['work_seconds']*1e3:.2f} | {parts} | {g['kernel_parallelism']:.1f} / {g['parallelism']:.1f} | {sp} | {f(m['threads_2.step_speedup'])} | {f(m['threads_2.kernel_speedup'])} |")
print("\n| kernel | threads | ns/elem-update median [range] | fraction of the same round's triad, median [range] | bit-identical |")
print("|---|---|---|---|---|")
for k in d["kernel"]:
    for t in k["kernel"]:
        print(f"| {k['kind']} {k['elements']} | {t['threads']} | {f(t['ns_per_elem_update'])} | {f(t['fraction_of_triad'])} | {t['bit_identical_to_one_thread']} |")
print("\n| step | threads | step ns/elem | lean step | kernel | check every step: overhead median [range] | every 10 | every 100 | first check ms |")
print("|---|---|---|---|---|---|---|---|---|")
for s in d["step"]:
    x = s["figures"]
    print(f"| {s['kind']} {s['elements']:.0f} | {s['threads']} | {f(x['ns_per_elem.step'])} | {f(x['ns_per_elem.lean_step'])} | {f(x['ns_per_elem.kernel'])} | {f(x['failure_check.every_1.overhead'])} | {f(x['failure_check.every_10.overhead'])} | {f(x['failure_check.every_100.overhead'])} | {f(x['failure_check.first_check_ms'])} |")
