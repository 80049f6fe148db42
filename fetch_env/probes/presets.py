"""Named probe settings (:data:`PROBE_PRESETS`), each with the evidence it was chosen on."""

from __future__ import annotations

from fetch_env.controller import RELAXATION_GAP
from fetch_env.probes.config import ProbeConfig

# Named probe settings: "env" is what the environments run at every reset (cheap);
# "measure" is what `food-fetch estimate` and the validation harness run: a 20 s hold, long
# enough for the slowest foods of the space (tau1 10 s; on 32 tuning foods tau1's 95th
# percentile was 18 % against the 6 s hold's 28 %, while a 1 ms relaxation step and a
# real-time 15 s hold at 2.5 ms were no better, 28 % and 30 %), and a 0.3 s slide, whose 30
# samples let estimate_friction find its plateau instead of falling back on the ratio's
# envelope (mu's median error on the 64 tuning foods 0.60 -> 0.52 %; its 95th percentile
# did not improve, 5.9 -> 7.0 %, until the envelope's quantile was raised).  Other holds,
# each calibrated on the 256 tuning foods and 8-fold cross-validated there (tau1 median /
# 95th percentile error, no noise): 14 s 2.7 / 21 %, 20 s 2.8 / 19 %, 27 s 2.8 / 22 %, 40 s
# 3.7 / 32 % (over a long hold the moment drifts by more than the relaxation left); log steps
# of 3 % instead of 5 % at 20 s: 3.1 / 19 %.  None is better than 20 s by more than the
# scatter between neighbours.  Other slides (the 256 tuning foods, uncalibrated, mu's median /
# 95th percentile error): this 2 mm in 0.3 s 0.09 / 4.1 %; 4 mm in 0.6 s 0.04 / 4.1 %; 4 mm
# in 0.3 s 0.06 / 5.0 %; slip strain 0.2 0.36 / 9.3 %, 0.05 0.15 / 4.5 %.  mu's tail is soft,
# large or high-friction pieces that roll and stick-slip under the blades, whatever the slide.


PROBE_PRESETS: dict[str, ProbeConfig] = {
    "env": ProbeConfig(),
    "measure": ProbeConfig(hold=20.0, slide_time=0.3, slip_envelope="per_blade"),
    # measure's probes with seven relaxation clamps at squeezes 0.0564-0.0636, whose medians
    # shrink the tails of g1 and tau1 a single clamp leaves (tau1's 95th percentile 17 -> 10 %
    # on the tuning foods, cross-validated; ProbeConfig.relaxation_repeats), and K1, K2, B
    # at the camera's contact angle (ProbeConfig.contact_angle)
    "repeated": ProbeConfig(hold=20.0, slide_time=0.3, slip_envelope="per_blade",
                            relaxation_repeats=7, contact_angle="camera"),
    # repeated's probes with a relaxation clamp whose blade contact is ~300 times stiffer
    # (only the blades', ProbeConfig.relaxation_contact_ratio; a cube's contact mesh finer),
    # friction nearly rigid (impratio 1e4: a held contact creeps ~ 1 / impratio) and a 1 ms
    # step that keeps so stiff a contact stable: the held moment then relaxes as the food
    # does (uncalibrated, one clamp, tuning foods: tau1 within about 0.5 % median where the
    # measure probes read 5 %; docs/estimator_validation.md), at about 5x the probes' cost
    #
    # Its slip probe starts the blades 0.1 mm from the food (slip_gap) and squeezes it by 3 %
    # (slip_strain) at a 2.5 ms step, so the blades lean in by a third of the angle they did
    # and their tips press less into a cube's sides (ProbeConfig.slip_gap), and reads the
    # two half-spoons' envelopes less the sensor's noise.  On the 512 tuning foods,
    # uncalibrated, mu's |error| (median / 90th / 95th percentile): the measure probes' slip
    # 0.10 / 2.1 / 4.2 %; gap 0.1 mm with squeeze 0.1 0.15 / 2.0 / 3.5 %, 0.05 0.08 / 1.2 /
    # 1.9 %, 0.03 0.07 / 0.9 / 1.5 %; 0.03 at 5 ms 0.05 / 0.8 / 1.3 %, at 2.5 ms 0.03 / 0.7 /
    # 1.3 %.  Slides of 0.2 or 0.45 s, 3 mm, a slower clamp or a longer hold moved the 95th
    # percentile by under 0.2 points either way.  The price is noise: with 1 % noise the smaller
    # forces read mu at 1.8 / 6.0 / 8.6 % (the measure slip 2.3 / 4.5 / 6.3 %).
    #
    # Which foods a single slide misses is chaotic (a slide of another speed misses others),
    # so the probe slides several times (five, below; first three, over 0.3, 0.45 and 0.2 s)
    # and takes the median (ProbeConfig.slip_repeats): on the 512 tuning foods, uncalibrated,
    # with three slides mu's |error| went
    # from 0.03 / 0.7 / 1.3 % (one slide) to 0.04 / 0.6 / 1.0 %, foods past 1.4 % from 19
    # to 14, the worst from 15 to 3.4 %; with 1 % noise from 1.80 / 6.0 / 8.6 % to 1.50 /
    # 4.5 / 5.6 % (benchmarks/slip_probe.py).  The slides' spread (diagnostic mu_trials, an
    # input of the error model) says which foods to trust: the 302 whose slides agreed within
    # 0.1 % were within 1.7 %.
    #
    # With sensor noise each slide reads the level its force ratio slips at from every
    # sample near it, not from one high quantile ("per_blade_slipping", SLIP_ENVELOPES),
    # and only where the blades press firmly (NOISY_SLIP_MIN_SHARE): without noise it reads
    # as before; with 1 % noise mu's |error| over the three slides (median / 90th / 95th
    # percentile / max) is 0.87 / 2.7 / 3.1 / 6 %, against 1.38 / 3.7 / 4.7 / 7 % for the
    # denoised envelope (512 tuning foods, benchmarks/slip_probe.py; read from every
    # gripping sample, 0.77 / 2.8 / 4.1 / 19 % and 1.50 / 4.5 / 5.6 / 16 %).  That level
    # still reads mu low under noise (mean -1.1 %: sticking samples just below mu that the
    # noise lifts into the slipping window), so the preset reads it less that bias,
    # extrapolated away ("per_blade_simex", estimators.slip_simex): 0.40 / 1.5 / 1.8 / 3.1 %,
    # mean -0.17 %, on the same slides with one noise draw each.
    #
    # Five slides rather than three (the next two of slide_times: 0.675 and 0.133 s, about
    # 0.3 s more of probes a food): under noise the median averages more of it away, and
    # the slides' spread then tells the foods the noise pushed far from those it did not.
    # On the 512 tuning foods' slides, three 1 % noise draws each (1536 readings,
    # uncalibrated; median / 90th / 95th percentile / max of |mu error|): three slides
    # 0.47 / 1.5 / 2.0 / 6.9 %, 21 readings past 3 %; five 0.40 / 1.3 / 1.7 / 5.3 %, 10.
    # To flag every reading past 3 % by the slides' spread (half their log-range) alone, three
    # slides need a limit of 0.0033, which flags 1168 of the 1462 readings within 2 %; five
    # 0.036, which flags 92 of 1484; to flag the one reading past 5 % (at 5.3 %, a half-range
    # of 0.068), 0.06, which flags 27 of 1484 and 2 of the 3 past 4 % (the limit
    # benchmarks.validate_estimators.RELIABILITY sets).  Without noise (the harness's tuning
    # run) 0.04 / 0.58 / 1.03 / 3.4 %, 14 foods past 1.4 %, went to 0.04 / 0.63 / 1.00 /
    # 3.4 %, 12.  Seven
    # slides did little better (with noise 0.36 / 1.3 / 1.6 / 4.4 %, 7 past 3 %, but their
    # spread flags 115 to flag those), and the longest read a few foods low without noise
    # (the 0.675 and 1.01 s slides alone 2.6 and 3.3 % at the 95th percentile, the 0.3 s
    # one 1.3 %).
    #
    # Its relaxation clamp's held food rings at the step's period under so stiff a contact,
    # so each solve starts from the step before last where the accelerations alternate
    # (relaxation_warmstart, fetch_env.warmstart): the same physics to the solver's
    # tolerance, in fewer Newton iterations (docs/benchmarks.md, "Where the simulations'
    # time goes").
    "precise": ProbeConfig(hold=20.0, slide_time=0.3, slip_envelope="per_blade_simex",
                           relaxation_repeats=7, contact_angle="camera",
                           relaxation_timestep=0.001, relaxation_impratio=1e4,
                           relaxation_contact_ratio=2.25, slip_gap=RELAXATION_GAP,
                           slip_strain=0.03, slip_timestep=0.0025, slip_repeats=5,
                           relaxation_warmstart="alternating"),
}

# Calibrations of the presets' systematic errors, fitted on the validation harness's tuning
# foods (benchmarks/validate_estimators.py --fit-calibration): they hold only for the
# settings of the preset they were fitted for.  A key "PRESET/LAYOUT-SCENES" holds the
# preset's calibration fitted on the pieces an environment of that layout and scene space
# draws (calibration_for).
