"""The tables of docs/perf/s16/3d_step.md from `flem bench step3` JSON and the last line of
tools/peers/akantu_3d_throughput.py: python3 3d_step_table.py flem.json akantu.out"""
import json,sys
fl=json.load(open(sys.argv[1]))
ak=json.loads(open(sys.argv[2]).read().strip().splitlines()[-1])
f=lambda x:"%.1f (%.1f-%.1f)"%(x["median"],x["min"],x["max"])
g=lambda x:"%.2f (%.2f-%.2f)"%(x["median"],x["min"],x["max"])
print("| kind | elements | clusters | colours | bytes/update | threads | kernel ns/update | kernel CPU ns | fraction of triad | step ns/update | bits = 1 thread |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for c in fl["cases"]:
    for t in c["threads"]:
        k=t["kernel"]; s=t["step"]
        print(f"| {c['kind']} | {c['elements']} | {c['clusters']} | {c['colours'][0]} | {c['bytes_per_element']['per_update_min']:.0f} | {t['threads']} | {f(k['ns_per_elem_update'])} | {k['cpu_ns_per_elem_update']['median']:.1f} | {g(k['fraction_of_triad'])} | {f(s['ns_per_elem_update'])} | {t['bit_identical_to_one_thread']} |")
print()
print("triad GB/s:", {k: f(v) for k,v in fl["triad_gb_per_s"].items()}, "load at end", fl["loadavg_at_end"])
print()
print("| mesh | elements | Akantu ns/update (wall) | median 50-step block | best block | CPU ns | cpu/wall | FLEM step, 1 thread (median) | ratio (wall, medians) | ratio (CPU) |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in ak["runs"]:
    c=[c for c in fl["cases"] if c["kind"]=="t4" and c["elements"]==r["n_elements"]][0]
    t1=[t for t in c["threads"] if t["threads"]==1][0]
    fs=t1["step"]["ns_per_elem_update"]["median"]; fc=t1["step"]["cpu_ns_per_elem_update"]["median"]
    t2=[t for t in c["threads"] if t["threads"]==2][0]["step"]["ns_per_elem_update"]["median"]
    print(f"| {r['mesh']} | {r['n_elements']} | {r['ns_per_element_update']:.1f} | {r['median_block_ns_per_element_update']:.1f} | {r['best_block_ns_per_element_update']:.1f} | {r['cpu_ns_per_element_update']:.1f} | {r['cpu_over_wall']} | {fs:.1f} (2 threads {t2:.1f}) | {r['median_block_ns_per_element_update']/fs:.1f} | {r['cpu_ns_per_element_update']/fc:.1f} |")
print("akantu load at end", ak["loadavg_at_end"])
