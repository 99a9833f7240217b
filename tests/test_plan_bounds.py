"""Plans with absurd values: a spec's duration_s and a plan file's arrays are held within the
bounds that keep a plan's arithmetic finite (docs/planning.md, plan files), and each refusal is
one line naming the key, or the file, the array and the bound."""

from __future__ import annotations

import dataclasses
import io
import re
import zipfile

import numpy as np
import pytest

from quatform import cli
from quatform.errors import InvalidInputError, ResourceLimitError
from quatform.plan_runs import scenario_with_plan
from quatform.planning import Plan, builtin_plan_specs, load_plan, load_plan_spec, make_plan
from quatform.planning.plan import PLAN_MAX_ABS, PLAN_MIN_STEP_S
from quatform.planning.spec import plan_spec_from_dict
from quatform.scenarios import load_scenario

TWO_BODIES = "belta-kumar-2002-two-bodies"


def _spec_file(tmp_path, duration):
    """The built-in two-body spec with its duration_s replaced."""
    src = builtin_plan_specs()[TWO_BODIES].read_text()
    f = tmp_path / "tiny.toml"
    f.write_text(re.sub(r"(?m)^duration_s = .*$", f"duration_s = {duration!r}", src))
    return f


def _pair_plan(**change):
    """A 5-knot plan of two robots in space, some arrays replaced."""
    t = np.linspace(0.0, 1.0, 5)
    p = np.stack([np.stack([t, 0 * t, 1 + 0 * t], -1), np.stack([t, 1 + 0 * t, 1 + 0 * t], -1)], 1)
    v = np.zeros_like(p)
    v[..., 0] = 1.0
    arrays = dict(times=t, positions=p, velocities=v, accelerations=np.zeros_like(p), masses=np.ones(2))
    return {**arrays, **change}


def _save(path, arrays):
    with open(path, "wb") as f:
        np.savez(f, format=np.array("quatform-plan-1"), info=np.array('{"name": "p"}'), **arrays)
    return path


def _one_line(capsys):
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and "warning" not in err, err
    assert len(err.splitlines()) == 1, err
    return err


# ------------------------------------------------------------------ duration_s


def test_a_duration_of_1e_300_is_refused_naming_duration_s():
    """Guards against: "accelerations contains -inf at index (0, 0, 0)", naming no key."""
    data = {"kind": "shaped-geodesic", "duration_s": 1e-300, "robots": {
        "masses": [1.0, 2.0], "start": [[1.0, 0.0], [-0.5, 0.0]], "goal": [[2.3, -0.7], [3.35, 0.35]]},
        "shaping": {"alpha": 0.99}}
    with pytest.raises(InvalidInputError, match=r"t\.toml: duration_s = 1e-300 s over knots = 201 .* at least 2e-10 s"):
        plan_spec_from_dict(data, where="t.toml")
    # a spec built in code is checked when planned, for both planners
    for name in (TWO_BODIES, "belta-kumar-2001-airplanes"):
        spec = dataclasses.replace(load_plan_spec(name), duration_s=1e-300)
        with pytest.raises(InvalidInputError, match=f"{name}: duration_s = 1e-300 s over knots"):
            make_plan(spec)


@pytest.mark.parametrize("masses", [[1e-9, 1.0], [1.0, 1e11], [1e-300, 1.0]])
def test_masses_too_far_apart_are_refused_naming_the_key_and_the_ratio(masses):
    """Guards against: masses [1e-9, 1] planned for ever (the geodesic's check integrates a metric that
    stiff in tiny steps), [1e-300, 1] said "all robots coincide" of robots apart."""
    data = {"kind": "shaped-geodesic", "duration_s": 20.0, "robots": {
        "masses": masses, "start": [[1.0, 0.0], [-0.5, 0.0]], "goal": [[2.3, -0.7], [3.35, 0.35]]},
        "shaping": {"alpha": 0.99}}
    with pytest.raises(InvalidInputError, match=r"t\.toml: \[robots\] masses = .* span a factor of .*, beyond "
                                                r"1e\+06"):
        plan_spec_from_dict(data, where="t.toml")
    data["robots"]["masses"] = [1.0]  # the file named in the other refusals of the masses too
    with pytest.raises(InvalidInputError, match=r"t\.toml: \[robots\] masses must be a 1-D array of N >= 2"):
        plan_spec_from_dict(data, where="t.toml")
    data["robots"]["masses"] = [1e-6, 1.0]  # at the bound (planned in 4 s)
    assert plan_spec_from_dict(data, where="t.toml").masses.tolist() == [1e-6, 1.0]


@pytest.mark.parametrize("name", [TWO_BODIES, "belta-kumar-2001-airplanes"])
def test_a_duration_whose_rates_leave_the_bound_names_the_shortest_one(name):
    """Guards against: a 1e-9 s plan had accelerations of 5e18 m/s^2 (and 1e-160 s ones overflowed)."""
    spec = dataclasses.replace(load_plan_spec(name), duration_s=1e-9)
    with pytest.raises(InvalidInputError, match=rf"{name}: duration_s = 1e-09 s makes the plan's accelerations "
                       r"reach .* beyond the bound 1e\+12 .* at least ([0-9.e+-]+) s") as info:
        make_plan(spec)
    shortest = float(re.search(r"at least ([0-9.e+-]+) s", str(info.value))[1])
    plan, _ = make_plan(dataclasses.replace(spec, duration_s=shortest))  # the quoted bound passes
    assert np.abs(plan.accelerations).max() <= PLAN_MAX_ABS


def test_cli_plan_with_duration_1e_300_says_one_line(tmp_path, capsys):
    rc = cli.main(["plan", str(_spec_file(tmp_path, 1e-300)), "--out", str(tmp_path / "p"), "--no-plots"])
    assert rc == 2
    assert "duration_s = 1e-300 s" in _one_line(capsys)
    assert not (tmp_path / "p").exists()


# ------------------------------------------------------------------ plan files


@pytest.mark.parametrize("change, array, shown", [
    (lambda a: {"velocities": np.full_like(a["velocities"], 1e308)}, "velocities", r"1e\+308 m/s"),
    (lambda a: {"positions": a["positions"] * 1e300}, "positions", r"1e\+300 m"),
    (lambda a: {"accelerations": np.full_like(a["accelerations"], np.inf)}, "accelerations", r"inf m/s\^2"),
    (lambda a: {"times": a["times"] * 1e13}, "times", r"2.5e\+12 s at index \(1,\)"),
    (lambda a: {"masses": np.array([1.0, np.nan])}, "masses", "nan kg"),
])
def test_a_plan_file_with_an_absurd_array_names_file_array_and_bound(tmp_path, change, array, shown):
    """Guards against: velocities of 1e308 were "the plan's robots meet (separation 0 m)", positions times
    1e300 "c contains inf"."""
    f = _save(tmp_path / "bad.npz", _pair_plan(**change(_pair_plan())))
    with pytest.raises(InvalidInputError, match=rf"bad\.npz: plan {array} holds {shown}.* beyond the bound "
                       r"\|value\| <= 1e\+12"):
        load_plan(f)


def test_a_plan_file_with_knots_closer_than_the_bound_is_refused(tmp_path):
    arrays = _pair_plan()
    arrays["times"] = arrays["times"] * 1e-13
    with pytest.raises(InvalidInputError, match=r"close\.npz: plan times 0 and 1 are 2\.5e-14 s apart, closer than "
                       r"the bound 1e-12 s"):
        load_plan(_save(tmp_path / "close.npz", arrays))
    assert PLAN_MIN_STEP_S == 1.0 / PLAN_MAX_ABS


def test_plans_at_the_bound_sample_finite_rates():
    """The bound's derivation (docs/planning.md): numbers within B = 1e12 and knots at least
    1/B apart keep every term of Plan.sample finite (here the extremes at once)."""
    B = PLAN_MAX_ABS
    for t in (np.array([0.0, 1.0 / B, B]), np.array([-B, B])):
        p = np.array([[[B, -B]], [[-B, B]], [[B, B]]])[:t.size]
        plan = Plan(t, p, -p, p, np.array([B]))
        with np.errstate(all="raise"):
            pos, vel, acc = plan.sample(np.concatenate([np.linspace(t[0], t[-1], 101), [1.0 / (2 * B)]]))
        assert np.isfinite(pos).all() and np.isfinite(vel).all() and np.isfinite(acc).all()


@pytest.mark.parametrize("scenario, change, array", [
    ("mas-kitts-helix", lambda a: {"velocities": np.full_like(a["velocities"], 1e308)}, "velocities"),
    ("mas-kitts-helix", lambda a: {"positions": a["positions"] * 1e300}, "positions"),
    ("team-three-bodies", lambda a: {"positions": a["positions"] * 1e300}, "positions"),
])
def test_cli_run_with_an_absurd_reference_says_one_line(tmp_path, capsys, scenario, change, array):
    f = _save(tmp_path / "bad.npz", _pair_plan(**change(_pair_plan())))
    rc = cli.main(["run", scenario, "--controller", "quaternion", "--reference", str(f), "--out",
                   str(tmp_path / "r"), "--no-plots", "--no-mcap"])
    assert rc == 2
    line = _one_line(capsys)
    assert f"{f}: plan {array} holds" in line and "beyond the bound |value| <= 1e+12" in line


# -- resource limits, plan files and spec keys -------------------------------------------------------

R2 = np.sqrt(2.0)


FIG3 = dict(masses=[1.0, 2.0], start=[[1.0, 0.0], [-0.5, 0.0]],
            goal=[[3 - R2 / 2, -R2 / 2], [3 + R2 / 4, R2 / 4]])


def _spec(**top):
    data = {"kind": "shaped-geodesic", "name": "t", "robots": dict(FIG3), "shaping": {"alpha": 0.7}}
    data.update(top)
    return data


def test_a_billion_knots_are_refused_up_front():
    """Guards against: knots = 10**9 was accepted and the planner tried to sample 1e9 knots."""
    with pytest.raises(ResourceLimitError, match=r"t\.toml: knots needs 1e\+09 steps"):
        plan_spec_from_dict(_spec(knots=10**9), where="t.toml")
    with pytest.raises(InvalidInputError, match="knots = 1000000000.0 must be an integer"):
        plan_spec_from_dict(_spec(knots=1e9), where="t.toml")


def _pair_plan_lasting(T):
    t = np.array([0.0, T])
    p = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]]] * 2)
    return Plan(t, p, np.zeros_like(p), np.zeros_like(p), np.ones(2), {"kind": "test", "name": "long"})


def test_a_reference_plan_lasting_1e9_s_is_refused_naming_the_file(tmp_path):
    """Guards against: the run was built for 1e9 s / dt_s = 1e11 steps (hours of work, terabytes)."""
    f = _pair_plan_lasting(1e9).save(tmp_path / "long.npz")
    sc = load_scenario("mas-kitts-yaw-step")
    with pytest.raises(ResourceLimitError, match=r"long\.npz: the plan's duration \(1e\+09 s\)"):
        scenario_with_plan(sc, f)
    ok = scenario_with_plan(sc, _pair_plan_lasting(5.0).save(tmp_path / "short.npz"))
    assert ok.duration_s == pytest.approx(5.0)


def _npz(entries: dict) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, raw in entries.items():
            zf.writestr(name + ".npy", raw)
    return buf.getvalue()


def _npy(arr) -> bytes:
    b = io.BytesIO()
    np.save(b, arr, allow_pickle=False)
    return b.getvalue()


def _header_only(shape, dtype="<f8") -> bytes:
    """A ``.npy`` header claiming ``shape`` with no data after it."""
    b = io.BytesIO()
    np.lib.format.write_array_header_1_0(b, {"descr": dtype, "fortran_order": False, "shape": shape})
    return b.getvalue()


def test_a_npy_header_claiming_1e13_elements_is_refused_before_allocating(tmp_path):
    """Guards against: np.load allocated the claimed 80 TB array (MemoryError traceback)."""
    good = {"format": _npy(np.array("quatform-plan-1")), "info": _npy(np.array("{}")),
            "masses": _npy(np.ones(2)), "times": _npy(np.array([0.0, 1.0]))}
    f = tmp_path / "huge.npz"
    f.write_bytes(_npz({**good, "positions": _header_only((10**13,))}))
    with pytest.raises(ResourceLimitError, match=r"huge\.npz: the array sizes in its \.npy headers"):
        load_plan(f)
    f.write_bytes(_npz({**good, "positions": _header_only((3,), "|O")}))
    with pytest.raises(InvalidInputError, match="entry 'positions' has dtype object"):
        load_plan(f)


@pytest.mark.parametrize("info, why", [("[1, 2]", "must be a JSON object"),
                                       ('{"a": ' * 50 + "1" + "}" * 50, "nested more than 8"),
                                       ("[" * 100000 + "]" * 100000, "must be a JSON object|not JSON")])
def test_a_plan_whose_info_is_a_list_or_nested_deep_is_refused(tmp_path, info, why):
    """Guards against: a list gave a TypeError traceback from dict(info); deep nesting a RecursionError."""
    plan = _pair_plan_lasting(1.0)
    f = tmp_path / "p.npz"
    with open(f, "wb") as fh:
        np.savez(fh, format=np.array("quatform-plan-1"), times=plan.times, positions=plan.positions,
                 velocities=plan.velocities, accelerations=plan.accelerations, masses=plan.masses,
                 info=np.array(info))
    with pytest.raises(InvalidInputError, match=why) as exc:
        load_plan(f)
    assert "\n" not in str(exc.value) and len(str(exc.value)) <= 500


@pytest.mark.parametrize("change, message", [
    ({"duratoin_s": 2.0}, "unknown key 'duratoin_s' at top level (did you mean 'duration_s'?)"),
    ({"duration_s": float("nan")}, "duration_s = nan must be finite"),
    ({"duration_s": -1.0}, "duration_s = -1.0 must be > 0"),
    ({"duration_s": "long"}, "duration_s = 'long' must be a number"),
    ({"min_clearance_m": {"x": 1}}, "min_clearance_m = {'x': 1} must be a number"),
    ({"shaping": {"alpah": 0.7}}, "unknown key 'alpah' at [shaping] (did you mean 'alpha'?)"),
    ({"shaping": {"alpha": float("inf")}}, "[shaping] alpha = inf must be finite"),
    ({"shaping": {"alpha": "0.7"}}, "[shaping] alpha = '0.7' must be a number"),
    ({"robots": {**FIG3, "mases": [1, 2]}}, "unknown key 'mases' at [robots] (did you mean 'masses'?)"),
    ({"robots": {**FIG3, "start": [[1.0, float("nan")], [0, 0]]}}, "[robots] start = nan must be finite"),
    ({"robots": {**FIG3, "start": [[1.0, "x"], [0, 0]]}}, "[robots] start = 'x' must be a number"),
    ({"robots": {**FIG3, "masses": [1.0, -2.0]}}, "positive"),
])
def test_spec_loader_refuses_bad_values_by_key(change, message):
    """Guards against: unknown keys were listed without the nearest valid one, a string alpha reached
    check_alpha, and the [robots] errors did not name the key."""
    data = _spec(**change)
    with pytest.raises(InvalidInputError) as exc:
        make_plan(plan_spec_from_dict(data, where="t.toml"))
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_rigid_spec_keys_name_the_nearest():
    """Guards against: [airplanes] unknown keys were listed without a suggestion; case was not a string check."""
    with pytest.raises(InvalidInputError, match=r"unknown key 'hh' at \[airplanes\] \(did you mean 'h'\?\)"):
        plan_spec_from_dict({"kind": "rigid-se3", "airplanes": {"hh": 1.0}}, where="a.toml")
    with pytest.raises(InvalidInputError, match=r"\[airplanes\] a = nan must be finite"):
        make_plan(plan_spec_from_dict({"kind": "rigid-se3", "airplanes": {"a": float("nan")}}, where="a.toml"))
    with pytest.raises(ResourceLimitError, match="knots"):
        plan_spec_from_dict({"kind": "rigid-se3", "knots": 10**10, "airplanes": {}}, where="a.toml")


def test_a_plan_with_a_negative_mass_is_refused(tmp_path):
    """Guards against: a plan.npz with masses = [-1, 1] was accepted by 'run --reference'."""
    plan, _ = make_plan(load_plan_spec("belta-kumar-2002-two-bodies"))
    with pytest.raises(InvalidInputError, match=r"plan masses\[0\] = -1 kg must be > 0"):
        dataclasses.replace(plan, masses=np.array([-1.0, 1.0]))
