"""Regenerates the direct shear meshes from direct_shear.geo (gmsh 4.15 Python package):
n = 1 -> direct_shear.msh (21 quads + 1 triangle), n = 2 -> direct_shear_fine.msh.
Run: /work/venv-mesh/bin/python configs/paper/gen_meshes.py"""
import os
import gmsh

here = os.path.dirname(os.path.abspath(__file__))
for n, name in [(1, "direct_shear.msh"), (2, "direct_shear_fine.msh")]:
    gmsh.initialize(["gmsh", "-setnumber", "n", str(n)])
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(os.path.join(here, "direct_shear.geo"))
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(os.path.join(here, name))
    types, tags, _ = gmsh.model.mesh.getElements(2)
    print(name, {gmsh.model.mesh.getElementProperties(t)[0]: len(x) for t, x in zip(types, tags)})
    gmsh.finalize()
