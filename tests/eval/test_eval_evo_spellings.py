"""evo's spellings on ``egs-bench ate`` / ``rpe`` (the same argument list given to evo's own
command-line functions gives the same numbers), ``--save_results`` JSON, and the Python API in
GT EST order against evo's API."""

import io
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from egs_bench.cli import main
from egs_bench.eval import trajectory_ate, trajectory_rpe
from egs_bench.geometry import read_tum
from tests.helpers.cli import assert_cli_error
from tests.helpers.trajectory_pairs import REAL, SYNTHETIC, pair_paths

GT_NAME, EST_NAME = "freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt"


def _evo(command: str, gt: Path, est: Path, extra: list[str], out: Path) -> zipfile.ZipFile:
    """evo_ape / evo_rpe's own command-line function (its parser and ``run``) on ``extra``."""
    if command == "ate":
        from evo.cli import ape as cli
        from evo.cli import ape_parser as parser
    else:
        from evo.cli import rpe as cli
        from evo.cli import rpe_parser as parser
    args = parser.parser().parse_args(["tum", str(gt), str(est), *extra, "--no_warnings",
                                       "--silent", "--save_results", str(out)])
    cli.run(args)
    return zipfile.ZipFile(out)


def _same(ours: dict, ref: zipfile.ZipFile) -> None:
    stats = json.loads(ref.read("stats.json"))
    for key in ("rmse", "mean", "median", "std", "min", "max"):
        assert ours["stats"][key] == pytest.approx(stats[key], rel=1e-10, abs=1e-14), key
    errors = np.load(io.BytesIO(ref.read("error_array.npy")))
    stamps = np.load(io.BytesIO(ref.read("timestamps.npy")))
    np.testing.assert_allclose(ours["errors"], errors, rtol=1e-10, atol=1e-14)
    np.testing.assert_array_equal(ours["timestamps_s"], stamps)


CASES = [
    ("ate", ["-a"]),
    ("ate", ["-as"]),
    ("ate", ["-a", "-s"]),
    ("ate", ["-a", "-r", "angle_deg"]),  # rotation ATE
    ("ate", ["-as", "--pose_relation", "angle_rad", "--t_max_diff", "0.02"]),
    ("rpe", ["-r", "angle_deg", "--delta_unit", "m", "-d", "1"]),
    ("rpe", ["--all_pairs", "-d", "10", "--t_max_diff", "0.02"]),
    ("rpe", ["-as", "-r", "trans_part"]),
    ("rpe", ["-a", "--pose_relation", "angle_deg", "--all_pairs", "-d", "5", "--delta_tol",
             "0.2"]),
]


@pytest.mark.parametrize(("est_name", "gt_name"), [SYNTHETIC, REAL[0]])
@pytest.mark.parametrize(("command", "extra"), CASES, ids=[" ".join(c[1]) for c in CASES])
def test_evo_spellings_give_evos_numbers(request: pytest.FixtureRequest, tmp_path: Path,
                                         command: Any, extra: Any, est_name: Any, gt_name: Any
                                         ) -> None:
    est, gt = pair_paths(request, tmp_path, est_name, gt_name)
    ref = _evo(command, gt, est, extra, tmp_path / "evo.zip")
    ours = tmp_path / "ours.json"
    assert main([command, str(gt), str(est), *extra, "--save_results", str(ours)]) == 0
    data = json.loads(ours.read_text())
    _same(data, ref)
    assert data["metric"] == command.upper() and data["reference"] == str(gt)


def test_a_flag_before_the_files_and_a_value_still_work(shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / "trajectories"
    gt, est = str(d / GT_NAME), str(d / EST_NAME)
    assert main(["ate", "-a", gt, est, "--save-results", str(tmp_path / "a.json")]) == 0
    assert main(["ate", gt, est, "-a", "se3", "--save-results", str(tmp_path / "b.json")]) == 0
    assert main(["ate", gt, est, "--align", "sim3", "--save-results",
                 str(tmp_path / "c.json")]) == 0
    a, b, c = (json.loads((tmp_path / f"{n}.json").read_text()) for n in "abc")
    assert a["stats"] == b["stats"] and a["settings"]["alignment"] == "se3"
    assert c["settings"]["alignment"] == "sim3" and c["stats"] != a["stats"]


def test_save_results_follows_the_output_rules(shared_data: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    d = shared_data / "trajectories"
    gt, est = str(d / GT_NAME), str(d / EST_NAME)
    out = tmp_path / "res.json"
    assert main(["ate", gt, est, "--save_results", str(out)]) == 0
    first = out.read_text()
    capsys.readouterr()
    code = main(["rpe", gt, est, "--save_results", str(out)])  # exists
    assert_cli_error(code, capsys.readouterr().err, 2, f"{out}: already exists; pass --overwrite")
    assert out.read_text() == first
    assert main(["rpe", gt, est, "--save_results", str(out), "--overwrite"]) == 0
    assert json.loads(out.read_text())["metric"] == "RPE"
    code = main(["ate", gt, est, "--save_results", str(tmp_path / "res.zip")])
    assert_cli_error(code, capsys.readouterr().err, 2, "name a .json file")
    assert not (tmp_path / "res.zip").exists()
    code = main(["ate", gt, est, "-s"])  # evo's scale-only correction: not offered
    assert_cli_error(code, capsys.readouterr().err, 2, "-s / --correct_scale needs -a")
    code = main(["ate", gt, est, "-r", "yaw"])
    assert_cli_error(code, capsys.readouterr().err, 2, "'yaw' is not one of 'trans_part'")


@pytest.mark.parametrize(("est_name", "gt_name"), [SYNTHETIC, REAL[0]])
def test_python_api_in_gt_est_order_equals_evos_api(request: pytest.FixtureRequest, tmp_path: Path,
                                                    est_name: Any, gt_name: Any) -> None:
    from evo.core import metrics, sync
    from evo.main_ape import ape
    from evo.main_rpe import rpe
    from evo.tools import file_interface

    est_path, gt_path = pair_paths(request, tmp_path, est_name, gt_name)
    for relation, member in (("trans_part", "translation_part"),
                             ("angle_deg", "rotation_angle_deg")):
        ref = file_interface.read_tum_trajectory_file(str(gt_path))
        est = file_interface.read_tum_trajectory_file(str(est_path))
        ref, est = sync.associate_trajectories(ref, est, max_diff=0.01)
        pose_relation = getattr(metrics.PoseRelation, member)
        evo_ape = ape(ref, est, pose_relation, align=True, correct_scale=True)
        ours = trajectory_ate(gt_path, est_path, align="sim3", relation=relation)
        assert ours.rmse == pytest.approx(evo_ape.stats["rmse"], rel=1e-10)
        assert ours.unit == ("m" if relation == "trans_part" else "deg")
        # the same from Trajectory objects, ground truth first
        same = trajectory_ate(read_tum(gt_path), read_tum(est_path), align="sim3",
                              relation=relation)
        assert same.rmse == ours.rmse
        ref = file_interface.read_tum_trajectory_file(str(gt_path))
        est = file_interface.read_tum_trajectory_file(str(est_path))
        ref, est = sync.associate_trajectories(ref, est, max_diff=0.01)
        evo_rpe = rpe(ref, est, pose_relation, delta=1, delta_unit=metrics.Unit.meters)
        ours_rpe = trajectory_rpe(gt_path, est_path, relation=relation, delta=1,
                                  delta_unit="m")
        assert ours_rpe.rmse == pytest.approx(evo_rpe.stats["rmse"], rel=1e-10)
    # the order matters: swapped files give other Sim(3) numbers
    swapped = trajectory_ate(est_path, gt_path, align="sim3")
    assert swapped.rmse != pytest.approx(trajectory_ate(gt_path, est_path,
                                                        align="sim3").rmse, rel=1e-3)
