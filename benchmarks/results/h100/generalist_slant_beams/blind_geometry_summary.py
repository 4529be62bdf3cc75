import sys, numpy as np, collections
rows=[l.split()[1:] for l in open(sys.argv[1]) if l.startswith("ROW")]
def cls(r):
    uw=int(r[4]); kind=r[5]; wall=int(r[6]); b,e,d,mr,tilt=map(float,r[7:12])
    fov = 45 if uw else 135
    if abs(e) > 45: where = "above" if e>0 else "below"
    elif abs(e) > 10: where = "slant_up" if e>0 else "slant_down"
    elif abs(b) > fov: where = "behind"
    else: where = "in_fan"
    return where
for test in ("held_out_layouts","random_trips"):
  for d in ("air_to_water","water_to_air"):
    sel=[r for r in rows if r[2]==test and r[3]==d]
    c=collections.Counter(cls(r) for r in sel)
    cu=collections.Counter((("water" if int(r[4]) else "air"), cls(r)) for r in sel)
    kinds=collections.Counter(("wall" if int(r[6]) else r[5]) for r in sel)
    print(test,d,len(sel),dict(c)); print("   ",dict(cu)); print("   ",dict(kinds))
    ins=[r for r in sel if cls(r)=="in_fan"]
    if ins: print("    in_fan: dist med %.2f, elev |med| %.1f, nearest range med %.2f, tilt med %.1f" % (np.median([float(r[9]) for r in ins]), np.median([abs(float(r[8])) for r in ins]), np.median([float(r[10]) for r in ins]), np.median([float(r[11]) for r in ins])))
