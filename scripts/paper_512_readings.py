"""Literal readings of the paper's 512 scheme: 8x8 groups, quarters A-D, even LEDs shifted."""
import itertools

import numpy as np

B = 8
def group_ids(shift, qperm, step):
    ids = np.zeros((B, B), int)
    odd_cells = [(i, j) for j in range(B) for i in range(B) if (i + j) % 2 == 0]
    for k, (i, j) in enumerate(odd_cells):
        ids[i, j] = 2 * k + 1
    even_cells = [(i, j) for j in range(B) for i in range(B) if (i + j) % 2 == 1]
    base = {c: 2 * k + 2 for k, c in enumerate(even_cells)}
    quarters = [(0, 0), (4, 0), (0, 4), (4, 4)]  # A B C D
    for q, (qi, qj) in enumerate(quarters):
        src = quarters[qperm[q]]
        for (i, j) in even_cells:
            if qi <= i < qi + 4 and qj <= j < qj + 4:
                li, lj = i - qi, j - qj
                # the LED now here came from `shift` steps back along `step` (wrapping in the quarter)
                si, sj = (li - shift * step[0]) % 4, (lj - shift * step[1]) % 4
                ids[i, j] = base[(src[0] + si, src[1] + sj)]
    return ids
def site(qswap, step):
    grid = np.zeros((32, 16), int)
    for g in range(8):
        qperm = qswap if g >= 4 else (0, 1, 2, 3)
        gi, gj = (g % 4) * 8, (g // 4) * 8
        grid[gi:gi + 8, gj:gj + 8] = group_ids(g % 4, qperm, step)
    return grid
def repeats(grid):
    seen, rep, border = {}, 0, 0
    C, R = grid.shape
    for i in range(C):
        for j in range(R):
            for di, dj in ((1, 0), (0, 1)):
                if i + di < C and j + dj < R:
                    a, b = grid[i, j], grid[i + di, j + dj]
                    key = (min(a, b), max(a, b))
                    cross_border = (i // 8 != (i + di) // 8) or (j // 8 != (j + dj) // 8)
                    if key in seen:
                        rep += 1
                        border += cross_border or seen[key]
                    else:
                        seen[key] = cross_border
    return rep, border
results = []
for step in [(1, 1), (1, -1), (2, 0), (0, 2), (1, 3)]:
    for qswap in itertools.permutations(range(4)):
        if qswap == (0, 1, 2, 3):
            continue
        results.append((repeats(site(qswap, step)), step, qswap))
results.sort()
print("best readings (repeated pairs, of which touching a group border):")
for r in results[:5]:
    print(r)
print("worst:", results[-1])
print("readings tried:", len(results), "; with zero repeats:", sum(r[0][0] == 0 for r in results))
