"""The check interval x dt study of the direct shear scene (docs/paper.md, issue 17).

cargo build --release
python3 docs/paper_studies/dsweep.py configs/paper/direct_shear.toml configs/paper/direct_shear.msh 1.4195e-4
(the last argument is dt_crit of the scene, from `flem check`). For dt in {1e-4 s (Table 1),
0.5 dt_crit, 0.8 dt_crit} and check_every in {1, 10, 100}: each p stage held 0.5 s of
simulated time (max_steps = 0.5 / dt); prints one markdown row per p stage. Writes dsw.toml
and dsw/ in the current folder (about 5 s in all).
"""
import subprocess,sys,json,re,os
ROOT=os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)),'..','..'))
FLEM=os.path.join(ROOT,'target','release','flem')
sys.path.insert(0,os.path.dirname(os.path.abspath(__file__))); import ana
base=open(sys.argv[1]).read()
msh=sys.argv[2]
crit=float(sys.argv[3])
res=[]
for dtname,dt in [('1e-4 (Table 1)',1e-4),('0.5 dt_crit',0.5*crit),('0.8 dt_crit',0.8*crit)]:
  for ce in [1,10,100]:
    s=base.replace('check_every = 10\n',f'check_every = {ce}\n')
    s=re.sub(r'\ndt = [0-9.e-]+ ',f'\ndt = {dt:.6e} ',s)
    n=int(round(0.5/dt))
    s=s.replace('max_steps = 5000',f'max_steps = {n}')
    s=s.replace('plots = true','plots = false').replace('snapshot_every = 1000','snapshot_every = 0')
    s=s.replace('file = "direct_shear','file = "'+ROOT+'/configs/paper/direct_shear')
    open('dsw.toml','w').write(s)
    r=subprocess.run([FLEM,'run','dsw.toml','--out','dsw','--quiet'],capture_output=True,text=True)
    if r.returncode: print(dtname,ce,'FAILED',r.stderr[-300:]); continue
    rows,j=ana.table('dsw',msh)
    for nme,sp,cv,fr,er,out in rows[1:]:
        cd=out['cd']; 
        others={k:v for k,v in out.items() if k not in('cd','bc')}
        oth=' '.join(f"{k}:{v[0]}/{v[1]}" for k,v in sorted(others.items()))
        print(f"| {dtname} | {ce} | {nme} | {sp} | {cd[0]}/{cd[1]} of {cd[2]} | {oth} | {'yes' if cv else 'no'} ({fr:.1e}) | {er:.1e} | {j['dt']:.2e} |",flush=True)
