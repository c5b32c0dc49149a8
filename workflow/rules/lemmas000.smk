# Paper 000's Lemma 1 (closed-form WV of a sinusoid, error O_p(1/T)), Lemma 2 (the WV identifies
# (alpha, beta): Jacobian rank, the objective along the alpha-beta ridge of Simulation 2's ridge
# fits), Remark A (efficient weights, measured on Simulation 2's per-replicate table) and the
# paired bootstrap of Fig 9's SD gaps (Simulation 1's table at its largest T). Config key
# `lemmas`; library code gmwm_studies.lemmas000. One job, under a core-minute at full scale
# (Lemma 1's simulations ~20 s, the ridge refits a few seconds each).
# Inputs: the per-replicate tables of the studies named by lemmas.sim2_study / lemmas.sim1_study
# (rule replicates), when those studies run; their parts are skipped otherwise.

LEMMAS = config["lemmas"]  # defaults: config.schema.yaml
LEMMAS.setdefault("seed", config["seed"])
LEMMAS_DIR = "reports/lemmas000"
LEMMAS_TABLES = ("lemma1_exact", "lemma1_rate", "lemma1_rate_detail", "lemma2_jacobian",
                 "lemma2_ridge", "remarkA_efficiency", "fig9_sd_gap")
LEMMAS_TITLES = {
    "lemma1_exact": "Lemma 1: library SIN WV vs the closed form (60-digit mpmath) and the Haar "
                    "filter response",
    "lemma1_rate": "Lemma 1: error of the empirical WV of a random-phase sinusoid, log-log slope "
                   "on T (T = 2^12 .. 2^20)",
    "lemma1_rate_detail": "Lemma 1: mean |WV error| per T and level against its exact mean and "
                          "bound",
    "lemma2_jacobian": "Lemma 2: relative Jacobian of the model WV at the truth and at the ridge "
                       "fits",
    "lemma2_ridge": "Lemma 2: the ridge fits' own objective along alpha * beta = const and at "
                    "the truth",
    "remarkA_efficiency": "Remark A: efficient vs CI weights on the same replicates (ratios "
                          "efficient / CI, paired bootstrap 95 % intervals)",
    "fig9_sd_gap": "Fig 9: MLE vs GMWM SD gap 1 - SD_MLE / SD_GMWM [%], paired bootstrap",
}


def _lemmas_sim2():
    name = LEMMAS["sim2_study"]
    if name not in STUDIES:
        return None
    s = STUDIES[name]
    return {"study": name, "T": max(s["n_samples"]), "seed": int(s["seed"]),
            "simulator": LEMMAS["sim2_simulator"] or s.get("simulator", "fast"),
            "levels": s.get("levels"),
            "estimators": {e: dict(config["estimators"][e]) for e in
                           (LEMMAS["base_estimator"], LEMMAS["efficient_estimator"])},
            "base": LEMMAS["base_estimator"], "efficient": LEMMAS["efficient_estimator"]}


def _lemmas_sim1():
    name = LEMMAS["sim1_study"]
    if name not in STUDIES:
        return None
    return {"study": name, "T": max(STUDIES[name]["n_samples"]), "mle": "mle",
            "parameters": list(LEMMAS["fig9_parameters"])}


def lemmas_targets():
    if not LEMMAS["enabled"]:
        return []
    return [f"{LEMMAS_DIR}/{t}.{ext}" for t in LEMMAS_TABLES for ext in ("csv", "md")]


def lemmas_benchmarks():
    return [f"{BENCH}/lemmas000/lemmas000.tsv"] if LEMMAS["enabled"] else []


if LEMMAS["enabled"]:
    register_section("lemmas000", {
        "model": "SIN; 2*AR1+2*SIN (Simulation 2); WN+RW+AR1+SIN (Simulation 1)",
        "description": (
            "[Vibration] Lemma 1 (sinusoid WV: exact closed form, O_p(1/T) error), Lemma 2 "
            "(identifiability: Jacobian rank, objective along the alpha-beta ridge), Remark A "
            "(efficient vs CI weights, Simulation 2) and Fig 9's SD gaps with paired bootstrap "
            "intervals (Simulation 1). [lemma1_rate](lemmas000/lemma1_rate.md)"),
        "n_samples": [2 ** int(t) for t in LEMMAS["log2_T"]],
        "replicates": int(LEMMAS["replicates"]),
        "targets": lemmas_targets(),
        "benchmarks": lemmas_benchmarks(),
    })


localrules:
    lemmas000,


rule lemmas000:
    input:
        sim2=(f"reports/{_lemmas_sim2()['study']}/replicates/estimates_T{_lemmas_sim2()['T']}.csv"
              if _lemmas_sim2() else []),
        sim1=(f"reports/{_lemmas_sim1()['study']}/replicates/estimates_T{_lemmas_sim1()['T']}.csv"
              if _lemmas_sim1() else []),
    output:
        tables=[f"{LEMMAS_DIR}/{t}.{ext}" for t in LEMMAS_TABLES for ext in ("csv", "md")],
    params:
        cfg={k: LEMMAS[k] for k in ("seed", "sinusoids", "exact_levels", "log2_T", "rate_levels",
                                    "replicates", "n_boot", "ridge_log10_beta", "ridge_max_fits")},
        sim2=_lemmas_sim2(),
        sim1=_lemmas_sim1(),
        titles=LEMMAS_TITLES,
    log:
        "logs/lemmas000.log",
    benchmark:
        f"{BENCH}/lemmas000/lemmas000.tsv"
    threads: 1
    resources:
        runtime=10,
        mem_mb=lambda wc: max(1000, int(8 * 2 ** max(LEMMAS["log2_T"]) * 16 * 3 / 1e6) + 500),
    script:
        "../scripts/lemmas000.py"
