# Geometric mean and range of the per-round ratios packets / one ray at a time: summarize.py FILE
import sys, collections, math
d = collections.defaultdict(lambda: collections.defaultdict(list))
for line in open(sys.argv[1]):
    r, s, o, t = line.split(); d[s][int(o)].append((int(r), float(t)))
for s in d:
    a = dict(d[s][0]); b = dict(d[s][1])
    ratios = [b[r] / a[r] for r in a if r in b]
    g = math.exp(sum(map(math.log, ratios)) / len(ratios))
    print(f"{s}: packets/scalar geo-mean {g:.3f} range {min(ratios):.3f}-{max(ratios):.3f}; best {min(b.values()):.4f} vs {min(a.values()):.4f}")
