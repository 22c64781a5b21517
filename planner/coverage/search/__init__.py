"""The search code the coverage methods are made of (`planner.coverage.methods`).

Modules: insertion (the edge-breaking rule, removal savings, route order),
gains (the fault-tolerant visibility V, kept up to date), objectives (So,
M_PTV, M_PTV2, per-distance), greedy (the RT / RD phases), local_search (the
moves of RT+LS), alns and alns_kernels (the ALNS), setcover and routing (the
dominating sets and OR-Tools routes of the baselines), baselines (B and C),
share (a second UAV at a viewpoint, where only that covers a target).
"""
