"""A scaling model of a run's phases, fitted to measured runs on 1 and 2 ranks
(docs/performance.md section 7, "Scaling model").

Each phase p (the per-phase times of summary.json ``phases`` and the set-up and (2.6)
diagnostic before the loop) costs, on P ranks for N dofs,

    T_p(N, P) = T_p(N) [s_p + (1 - s_p) / P] + C_p(N, P)

- T_p(N) = T_p(N_ref) (N / N_ref)^e_p: the serial time, e_p fitted by least squares on
  log T against log N over the serial runs;
- s_p: the part that does not divide among the ranks (Amdahl), max(0, 2 T_p(N, 2) /
  T_p(N, 1) - 1) from the runs on 1 and 2 ranks at the largest N measured on both;
- C_p: the latency of the Krylov phase's communication, which the 2-rank runs on one
  machine do not show: per CG iteration two global reductions (CG's inner products,
  ALPHA log2 P each) and HALOS neighbour exchanges (the matrix-vector products of the
  V-cycle's levels, ALPHA each); the CG iterations grow as N^e_cg (fitted).

The phase that stops scaling first is the one whose parallel efficiency T_p(N, 1) /
(P T_p(N, P)) falls below one half at the fewest ranks while it takes at least
SIGNIFICANT of the predicted total (a phase of a second that stops scaling stops nothing).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

PHASES = ("set-up", "before the loop", "Krylov solves", "preconditioner set-up",
          "residual assembly", "Jacobian assembly", "other SNES work", "outputs")
ALPHA = 5e-6        # s per message (a cluster's MPI latency, 1-5 us: the pessimistic end)
HALOS = 30          # neighbour exchanges per CG iteration (6 fine-level products, 4-5 levels)
SIGNIFICANT = 0.1   # the share of the total from which a phase that stops scaling counts


def phases(summary: dict) -> dict:
    """The per-phase times of one run.

    Args:
        summary: a run's summary.json (with ``phases``).

    Returns:
        {phase: seconds} over PHASES, plus "dofs", "ranks" and "cg" (the CG iterations).
    """
    petsc, stages = summary["phases"]["petsc"], summary["phases"]["stages"]
    before = summary["wall_s"] - summary["setup_s"] - summary["loop_s"]
    times = [summary["setup_s"], before, petsc["Krylov solves"],
             petsc["preconditioner set-up"], petsc["residual assembly"],
             petsc["Jacobian assembly"], stages["solve"] - sum(petsc.values()),
             stages["outputs"]]
    row = dict(zip(PHASES, times))
    row.update(dofs=summary["mesh"]["dofs"], ranks=summary["mpi_ranks"],
               cg=sum(s["linear_iterations"] for s in summary["steps"]))
    return row


def fit(rows: list[dict]) -> dict:
    """The model's constants from measured runs.

    Args:
        rows: ``phases`` of serial runs at two or more sizes and of 2-rank runs.

    Returns:
        {"ref": the largest serial row measured on 2 ranks too, "exponent": {phase: e_p},
        "serial": {phase: s_p}, "cg_exponent": e_cg}.
    """
    one = sorted((r for r in rows if r["ranks"] == 1), key=lambda r: r["dofs"])
    two = {r["dofs"]: r for r in rows if r["ranks"] == 2}
    if len(one) < 2 or not any(r["dofs"] in two for r in one):
        raise ValueError("the model needs serial runs at two sizes or more and a 2-rank run "
                         "at one of them")
    ref = [r for r in one if r["dofs"] in two][-1]
    x = np.log([r["dofs"] for r in one])

    def slope(key):
        return float(np.polyfit(x, np.log([max(r[key], 1e-9) for r in one]), 1)[0])

    return {"ref": ref, "exponent": {p: slope(p) for p in PHASES},
            "serial": {p: max(0.0, 2.0 * two[ref["dofs"]][p] / ref[p] - 1.0) if ref[p] > 0
                       else 0.0 for p in PHASES},
            "cg_exponent": slope("cg")}


def predict(model: dict, dofs: int, ranks: int) -> dict:
    """The predicted time of each phase.

    Args:
        model: ``fit``'s result.
        dofs: N.
        ranks: P.

    Returns:
        {phase: seconds} and "total".
    """
    ref, scale = model["ref"], dofs / model["ref"]["dofs"]
    out = {}
    for p in PHASES:
        serial = ref[p] * scale ** model["exponent"][p]
        s = model["serial"][p]
        out[p] = serial * (s + (1.0 - s) / ranks)
    if ranks > 1:
        cg = ref["cg"] * scale ** model["cg_exponent"]
        out["Krylov solves"] += cg * ALPHA * (2.0 * np.log2(ranks) + HALOS)
    out["total"] = sum(out[p] for p in PHASES)
    return out


def first_to_stop(model: dict, dofs: int, max_ranks: int = 4096) -> tuple[str, int] | None:
    """The phase whose parallel efficiency falls below one half at the fewest ranks among
    those that take at least SIGNIFICANT of the total there.

    Args:
        model: ``fit``'s result.
        dofs: N.
        max_ranks: the largest P looked at (powers of two).

    Returns:
        (phase, P), or None if every phase keeps half its efficiency up to max_ranks.
    """
    base = predict(model, dofs, 1)
    ranks = 2
    while ranks <= max_ranks:
        at = predict(model, dofs, ranks)
        low = [p for p in PHASES if base[p] > 0 and base[p] / (ranks * at[p]) < 0.5
               and at[p] >= SIGNIFICANT * at["total"]]
        if low:
            return max(low, key=lambda p: at[p]), ranks
        ranks *= 2
    return None


def main(argv: list[str]) -> None:
    """Print the model fitted to run directories (each with summary.json) and its
    predictions: ``.venv/bin/python -m vpcontact.studies.scaling DOFS P1,P2,... RUN_DIR...``.

    Args:
        argv: the dofs to predict for, the rank counts, then the run directories.
    """
    dofs, ranks = int(argv[0]), [int(p) for p in argv[1].split(",")]
    rows = [phases(json.loads((Path(d) / "summary.json").read_text())) for d in argv[2:]]
    model = fit(rows)
    print("| phase | exponent e_p | part on one rank s_p | "
          + " | ".join(f"{p} ranks" for p in ranks) + " |")
    print("|---|---|---|" + "---|" * len(ranks))
    at = [predict(model, dofs, p) for p in ranks]
    for p in PHASES:
        print(f"| {p} | {model['exponent'][p]:.2f} | {model['serial'][p]:.2f} | "
              + " | ".join(f"{a[p]:.1f} s" for a in at) + " |")
    print("| total | | | " + " | ".join(f"{a['total']:.1f} s" for a in at) + " |")
    stop = first_to_stop(model, dofs)
    print(f"CG iterations grow as N^{model['cg_exponent']:.2f}; first to stop scaling: "
          + (f"{stop[0]} (below half its efficiency from {stop[1]} ranks)" if stop
             else "none up to 4096 ranks"))


if __name__ == "__main__":
    import sys
    main(sys.argv[1:])
