"""The opening model's crack threshold against the check interval and dt (docs/paper.md).

cargo build --release
python3 docs/paper_studies/othreshold.py configs/paper/opening.toml 1.3875e-4 110
(dt_crit of the scene from `flem check`; the first stage's level). For dt in {1e-4 s (Table 1),
0.5 dt_crit, 0.8 dt_crit} and check_every in {1, 10, 100}: stage 1 at the first level (to
rest), stage 2 at p held 600 steps; bisects the smallest p that splits to 1/16. Also the
state at the config's own levels. Writes othr.toml and othr/ in the current folder.
"""
import json, os, re, subprocess, sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
FLEM = os.path.join(ROOT, 'target', 'release', 'flem')
base, crit, p1 = open(sys.argv[1]).read(), float(sys.argv[2]), float(sys.argv[3])


def run(dt, ce, p2, steps2=600):
    s = re.sub(r'\ndt = [0-9.e-]+ ', f'\ndt = {dt:.6e} ', base)
    s = s.replace('check_every = 10\n', f'check_every = {ce}\n').replace('check_every = 20\n', f'check_every = {ce}\n')
    a, b = s.index('[[stage]]'), s.index('[output]')
    s = s[:a] + f'[[stage]]\nname = "first"\nlevels = {{ p = {p1}, p_bottom = {p1} }}\nmax_steps = 8000\n\n[[stage]]\nname = "second"\nlevels = {{ p = {p2}, p_bottom = {p2} }}\nmax_steps = {steps2}\n\n' + s[b:]
    s = s.replace('plots = true', 'plots = false').replace('snapshot_on_split = true', 'snapshot_on_split = false')
    open('othr.toml', 'w').write(s)
    subprocess.run([FLEM, 'run', 'othr.toml', '--out', 'othr', '--quiet'], capture_output=True, check=True)
    j = json.load(open('othr/summary.json'))
    return j['stages'][0]['splits'], j['stages'][1]['splits'], j['crack_faces']['separated_both_ends']


for name, dt in [('1e-4 (Table 1)', 1e-4), ('0.5 dt_crit', 0.5 * crit), ('0.8 dt_crit', 0.8 * crit)]:
    for ce in [1, 10, 100]:
        lo, hi = p1, p1 * 1.2
        s1, _, _ = run(dt, ce, hi)
        while hi - lo > 1.0 / 16:
            mid = 0.5 * (lo + hi)
            if run(dt, ce, mid)[1] > 0:
                hi = mid
            else:
                lo = mid
        print(f'| {name} | {ce} | splits at {p1}: {s1} | threshold ({lo:.3f}, {hi:.3f}] |', flush=True)
