"""The lowest mode a scene's load excites, for the choice of the paper's eta (docs/paper.md).

python3 docs/paper_studies/omega0.py SCENE 'LEVELS' COL [COL2]
The scene's cracking and stages are replaced by one undamped, uncracked dynamic stage at LEVELS (a TOML inline table,
e.g. '{ p = 100.0, p_bottom = 100.0 }') of 3000 steps, history every step; prints the five
strongest angular frequencies (rad/s, 10 rad/s bins) of the history column COL (minus COL2).
Used: opening.toml '{ p = 100.0, p_bottom = 100.0 }' top_uy bot_uy (a probe "bot" at (6, 0) is
added) -> 1220 rad/s (the 2920 rad/s peak is the stretch mode); direct_shear.toml
'{ q = 100.0 }' a_uy -> 1700 rad/s. Writes omega0.toml and omega0/ in the current folder.
"""
import csv, math, os, re, subprocess, sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
scene, levels, col = sys.argv[1], sys.argv[2], sys.argv[3]
col2 = sys.argv[4] if len(sys.argv) > 4 else None
s = open(scene).read()
a, b = s.index('[[stage]]'), s.index('[output]')
c = s.index('[cracking]')  # no cracking: the elastic modes (the cracking tables precede the stages)
s = s[:c] + f'[[stage]]\nname = "dyn"\nlevels = {levels}\ndynamic = true\nmax_steps = 3000\n\n' + s[b:]
s = re.sub(r'damping = \{[^}]*\}', 'damping = { type = "none" }', s)
s = re.sub(r'history_every = \d+', 'history_every = 1', s)
s = s.replace('plots = true', 'plots = false').replace('snapshot_on_split = true', 'snapshot_on_split = false')
s = re.sub(r'snapshot_every = \d+', 'snapshot_every = 0', s)
s = s.replace('probes = [', 'probes = [{ name = "bot", at = [6.0, 0.0] }, ')
s = s.replace('file = "direct_shear', 'file = "' + os.path.join(ROOT, 'configs/paper/direct_shear'))
open('omega0.toml', 'w').write(s)
subprocess.run([os.path.join(ROOT, 'target/release/flem'), 'run', 'omega0.toml', '--out', 'omega0', '--quiet'], check=True)
r = list(csv.DictReader(open('omega0/history.csv')))
t = [float(x['time']) for x in r]
u = [float(x[col]) - (float(x[col2]) if col2 else 0.0) for x in r]
m = sum(u) / len(u)
u = [x - m for x in u]
pw = []
for k in range(1, 600):
    w = 10.0 * k
    c = sum(ui * math.cos(w * ti) for ui, ti in zip(u, t))
    sn = sum(ui * math.sin(w * ti) for ui, ti in zip(u, t))
    pw.append((c * c + sn * sn, w))
pw.sort(reverse=True)
print('strongest (power, rad/s):', [(round(p, 2), w) for p, w in pw[:5]])
