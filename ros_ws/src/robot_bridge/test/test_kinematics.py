"""robot_bridge.kinematics: IK along paths, rejections, time parameterisation, FK against MuJoCo."""
import mujoco
import numpy as np
import pytest

from robot_bridge.kinematics.arm import BAXTER_RIGHT_JOINTS, ArmKinematics, default_urdf_path
from robot_bridge.kinematics.example_paths import deployment_like_path
from robot_bridge.kinematics.gripper_path import GripperPath, PathRejected, read_gripper_csv, write_gripper_csv
from robot_bridge.kinematics.planner import ArmCommandPlanner, BridgeConfig
from robot_bridge.kinematics.timing import LimitViolation, time_parameterise
from robot_bridge.sim.experiment import ArmSpec, ExperimentSpec
from robot_bridge.sim.mjcf_builder import build_mjcf


@pytest.fixture(scope='module')
def planner():
    return ArmCommandPlanner(BridgeConfig())


def _short_path(n=20, duration_s=2.0):
    return deployment_like_path(n_poses=n, duration_s=duration_s, height_m=(0.35, 0.5), max_tilt_rad=0.5)


def test_ik_follows_reachable_deployment_paths_to_a_tenth_of_a_millimetre(planner):
    for path in (deployment_like_path(), deployment_like_path(radius_m=0.2)):
        plan = planner.plan(path)
        err = plan.tracking_error
        assert err['position_max_m'] <= 1e-4 and err['orientation_max_rad'] <= 1e-3
        # independent check of the reported error: FK of the solution against the targets
        targets = planner.to_base(path)
        fk = np.array([planner.arm.gripper_pose(q) for q in plan.trajectory.q])
        assert np.max(np.linalg.norm(fk[:, :3, 3] - targets[:, :3, 3], axis=1)) <= 1e-4
        lim = planner.arm.limits
        assert np.all(plan.trajectory.q >= lim.lower) and np.all(plan.trajectory.q <= lim.upper)


def test_executed_path_of_the_planned_joints_is_the_requested_path(planner):
    path = _short_path()
    plan = planner.plan(path)
    back = planner.executed_path(path.t_s, plan.trajectory.q)
    assert np.max(np.abs(back.xyz_m - path.xyz_m)) < 1e-4
    dots = np.abs(np.sum(back.quat_xyzw * path.quat_xyzw, axis=1))        # q and -q are the same rotation
    assert np.all(dots > 1.0 - 1e-6)


def test_pinocchio_fk_matches_mujoco_fk_of_the_same_urdf():
    urdf = default_urdf_path()
    arm = ArmKinematics(urdf, 'base', 'right_gripper', BAXTER_RIGHT_JOINTS)
    spec = ExperimentSpec(ArmSpec(urdf, 'base', 'right_gripper', list(BAXTER_RIGHT_JOINTS)), None,
                          np.array([0.0, 0.0, -9.81]))
    model = mujoco.MjModel.from_xml_string(build_mjcf(spec, with_object=False).xml)
    data = mujoco.MjData(model)
    qpos = [model.jnt_qposadr[model.joint(n).id] for n in BAXTER_RIGHT_JOINTS]
    site = model.site('grasp').id
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = rng.uniform(arm.limits.lower, arm.limits.upper)
        data.qpos[qpos] = q
        mujoco.mj_kinematics(model, data)
        pose = arm.gripper_pose(q)
        assert np.allclose(pose[:3, 3], data.site_xpos[site], atol=1e-9)
        assert np.allclose(pose[:3, :3], data.site_xmat[site].reshape(3, 3), atol=1e-9)


def test_gripper_frame_points_down_in_the_contracts_hanging_pose(planner):
    """Quaternion (1, 0, 0, 0) (+z_gripper = -z_table) is reached, and +z of Baxter's right_gripper (between the
    fingers) is then the table's -z: the default grasp offset puts +z_gripper along the approach axis."""
    path = GripperPath(np.array([0.0]), np.array([[0.0, 0.0, 0.4]]), np.array([[1.0, 0.0, 0.0, 0.0]]))
    plan = planner.plan(path)
    tip = planner.arm.gripper_pose(plan.trajectory.q[0])
    assert np.allclose(np.linalg.inv(planner.table)[:3, :3] @ tip[:3, 2], [0.0, 0.0, -1.0], atol=1e-6)


def _rejected(planner, path) -> PathRejected:
    with pytest.raises(PathRejected) as info:
        planner.plan(path)
    return info.value


def test_rejections_name_the_first_bad_pose(planner):
    assert 'empty' in str(_rejected(planner, GripperPath(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)))))

    path = _short_path()
    path.xyz_m[7, 1] = np.nan
    exc = _rejected(planner, path)
    assert exc.index == 7 and 'NaN' in str(exc) and 'pose 7 (t = 0.737 s' in str(exc)

    path = _short_path()
    path.t_s[5] = path.t_s[4]
    exc = _rejected(planner, path)
    assert exc.index == 5 and 'does not increase' in str(exc)

    path = _short_path()
    path.xyz_m[12] += [0.0, 0.0, 2.0]           # 2 m above the others: out of reach
    exc = _rejected(planner, path)
    assert exc.index == 12 and 'unreachable' in str(exc) and exc.xyz == pytest.approx(path.xyz_m[12].tolist())

    # this circle passes by a wrist singularity near its end: w0 would have to swing by more than a radian
    exc = _rejected(planner, deployment_like_path(radius_m=0.10))
    assert exc.index == 191 and 'singularity' in str(exc) and 'right_w0' in str(exc)


def test_a_pose_that_needs_a_joint_beyond_its_limit_is_rejected_naming_the_joint(tmp_path):
    """Lower right_e1's upper limit (URDF edit) below what the path needs: reachable without limits, not with."""
    urdf = tmp_path / 'narrow_elbow.urdf'
    urdf.write_text(default_urdf_path().read_text().replace('lower="-0.05" upper="2.618"', 'lower="-0.05" upper="0.9"'))
    planner = ArmCommandPlanner(BridgeConfig(urdf=str(urdf)))
    exc = _rejected(planner, _short_path())
    assert 'right_e1' in str(exc) and 'beyond its limits' in str(exc)


def test_time_parameterisation_keeps_feasible_stamps_and_slows_down_otherwise(planner):
    lim = planner.arm.limits
    path = _short_path(n=30, duration_s=30.0)             # slow: stamps kept
    slow = planner.plan(path)
    assert slow.trajectory.time_scale == 1.0 and np.allclose(slow.trajectory.t_s, path.t_s)
    fast = planner.plan(_short_path(n=30, duration_s=0.5))  # far too fast: slowed down
    tr = fast.trajectory
    assert tr.time_scale > 1.0 and 'slowed down' in tr.note
    assert np.allclose(tr.q, slow.trajectory.q, atol=1e-6)
    # the limits hold on a fine grid of the retimed spline, not only at the poses
    grid = np.linspace(0.0, tr.t_s[-1], 5000)
    _, qd, qdd = tr.sample(grid)
    assert np.all(np.abs(qd) <= planner.velocity_limit * (1 + 1e-6))
    assert np.all(np.abs(qdd) <= planner.acceleration_limit * (1 + 1e-2))   # cubic: qdd linear between samples
    assert np.max(np.abs(qd) / planner.velocity_limit) > 0.5 or np.max(np.abs(qdd) / planner.acceleration_limit) > 0.5
    assert np.all(tr.q >= lim.lower) and np.all(tr.q <= lim.upper)


def test_time_parameterisation_rejects_a_spline_leaving_a_position_limit():
    t = np.array([0.0, 1.0, 3.0])
    q = np.array([[0.0], [0.99], [0.9]])      # every pose inside [-1, 1]; the spline reaches 1.26 after pose 1
    with pytest.raises(LimitViolation, match='outside its limits') as info:
        time_parameterise(t, q, np.array([-1.0]), np.array([1.0]), np.array([10.0]), np.array([100.0]), ['j'])
    assert info.value.index == 1


def test_csv_round_trip_and_bad_csv(tmp_path, planner):
    path = _short_path()
    write_gripper_csv(tmp_path / 'g.csv', path)
    back = read_gripper_csv(tmp_path / 'g.csv')
    assert np.allclose(back.xyz_m, path.xyz_m) and np.allclose(back.t_s, path.t_s)
    (tmp_path / 'bad.csv').write_text('t,x,y,z\n0,1,2,3\n')
    with pytest.raises(ValueError, match='lacks column'):
        read_gripper_csv(tmp_path / 'bad.csv')


def test_cli_writes_a_joint_trajectory_or_exits_2(tmp_path, capsys):
    from robot_bridge.cli.robot_bridge_cli import main
    write_gripper_csv(tmp_path / 'g.csv', _short_path())
    assert main(['plan', str(tmp_path / 'g.csv'), '--out', str(tmp_path / 'q.csv')]) == 0
    data = np.loadtxt(tmp_path / 'q.csv', delimiter=',', skiprows=1)
    assert data.shape == (20, 1 + 3 * 7)
    bad = _short_path()
    bad.xyz_m[3, 0] = np.inf
    write_gripper_csv(tmp_path / 'bad.csv', bad)
    assert main(['plan', str(tmp_path / 'bad.csv'), '--out', str(tmp_path / 'q2.csv')]) == 2
    assert 'robot-bridge: error: pose 3' in capsys.readouterr().err
    assert not (tmp_path / 'q2.csv').exists()
