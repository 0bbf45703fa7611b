# Renders docs/liver.png from the last frame of `raisov run examples/liver_grasp.toml`
# (run from the repository root; needs meshio, matplotlib and numpy from PyPI).
import meshio, numpy as np, glob, matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
f = sorted(glob.glob("raisov-out/liver-grasp/frames/*.vtu"))[-1]
m = meshio.read(f)
X = m.points; u = m.point_data["displacement"]; x = X + u
tets = m.cells_dict["tetra"]
faces = {}
for t in tets:
    for tri in ((t[0],t[2],t[1]),(t[0],t[1],t[3]),(t[0],t[3],t[2]),(t[1],t[2],t[3])):
        k = tuple(sorted(tri)); faces[k] = None if k in faces else tri
bnd = np.array([v for v in faces.values() if v is not None])
mag = np.linalg.norm(u, axis=1) * 1000
fig = plt.figure(figsize=(8, 5.2), dpi=110)
ax = fig.add_subplot(111, projection="3d")
tri = x[bnd]
c = mag[bnd].mean(axis=1)
norm = matplotlib.colors.Normalize(vmin=0, vmax=mag.max())
cmap = matplotlib.cm.viridis
n = np.cross(tri[:,1]-tri[:,0], tri[:,2]-tri[:,0]); n /= np.linalg.norm(n,axis=1)[:,None]+1e-30
light = np.array([0.4,-0.6,0.7]); light/=np.linalg.norm(light)
shade = 0.55+0.45*np.clip(n@light,0,1)
cols = cmap(norm(c)); cols[:,:3]*=shade[:,None]
pc = Poly3DCollection(tri*1000, facecolors=cols, edgecolors="none")
ax.add_collection3d(pc)
lo, hi = x.min(0)*1000, x.max(0)*1000
ax.set_xlim(lo[0],hi[0]); ax.set_ylim(lo[1],hi[1]); ax.set_zlim(lo[2],hi[2])
ax.set_box_aspect(hi-lo)
ax.view_init(elev=18, azim=-60)
ax.set_xlabel("x (mm)"); ax.set_ylabel("y (mm)"); ax.set_zlabel("z (mm)")
sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
cb = fig.colorbar(sm, ax=ax, shrink=0.7, pad=0.1); cb.set_label("|displacement| (mm)")
ax.set_title("Liver L1 (7547 nodes), held at its top, grasped and pulled 2 cm\n(examples/liver_grasp.toml, t = 1 s)", fontsize=10)
plt.tight_layout()
plt.savefig("docs/liver.png")
print(f, len(bnd), mag.max())
