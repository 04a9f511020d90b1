//! Probabilistic roadmap, graph search, hybrid PRM-RL executor and plan validation; no IO.
