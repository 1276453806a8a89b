"""Maps over two controls (`vibro map`): ROP and impact-pattern grids, bifurcation diagrams, their figures."""
