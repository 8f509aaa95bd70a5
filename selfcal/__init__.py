"""scorbot-selfcal's public API: load a robot, import and read a dataset, calibrate it by its
route, evaluate the calibration on held-out data, read and write a calibration, deploy it, the
camera models, the targets and the exception root. docs/api.md shows them at work.

SI units (m, rad) inside, as everywhere in the package; each name's docstring states its units
and frames. The names load on first use (PEP 562): ``import selfcal`` reads neither numpy,
scipy nor OpenCV, so that every ``selfcal.*`` import (the command line's too) stays cheap. The
computing functions (:func:`calibrate`, :func:`evaluate`) run with the command's BLAS/OpenMP
thread limit (``SELFCAL_THREADS``, else 1; :func:`selfcal.threads.limited`).
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as such)
if TYPE_CHECKING:
    from selfcal.calibration.board.evaluate import Evaluation as Evaluation
    from selfcal.calibration.drift.images import check_images as check_images
    from selfcal.calibration.drift.verdict import ImageDriftCheck as ImageDriftCheck
    from selfcal.calibration.field.calibrate import (
        CalibrationFailedError as CalibrationFailedError,
    )
    from selfcal.calibration.handeye.calibrate import HandEyeCalibration as HandEyeCalibration
    from selfcal.calibration.handeye.calibration_file import HandEyeFile as HandEyeFile
    from selfcal.calibration.routes import calibrate as calibrate
    from selfcal.calibration.routes import calibration_route as calibration_route
    from selfcal.calibration.routes import dataset_route as dataset_route
    from selfcal.calibration.routes import evaluate as evaluate
    from selfcal.calibration.routes import open_dataset as open_dataset
    from selfcal.calibration.routes import read_calibration as read_calibration
    from selfcal.calibration.routes import write_calibration as write_calibration
    from selfcal.calibration.tracker.calibrate import TrackerRun as TrackerRun
    from selfcal.calibration.tracker.calibrate import calibrate_tracker as calibrate_tracker
    from selfcal.calibration.tracker.calibration_file import (
        TrackerCalibration as TrackerCalibration,
    )
    from selfcal.calibration.tracker.drift import DriftCheck as DriftCheck
    from selfcal.calibration.tracker.drift import check_tracker as check_tracker
    from selfcal.calibration.tracker.identify import TrackerMeasurements as TrackerMeasurements
    from selfcal.calibration.tracker.identify import identify_tracker as identify_tracker
    from selfcal.camera import BrownConrady as BrownConrady
    from selfcal.camera import CameraModel as CameraModel
    from selfcal.camera import DoubleSphere as DoubleSphere
    from selfcal.camera import Fisheye as Fisheye
    from selfcal.camera import Pinhole as Pinhole
    from selfcal.camera import Rig as Rig
    from selfcal.camera import camera_model as camera_model
    from selfcal.errors import EstimationError as EstimationError
    from selfcal.errors import HardwareError as HardwareError
    from selfcal.errors import InputError as InputError
    from selfcal.errors import SelfCalError as SelfCalError
    from selfcal.errors import SelfCalWarning as SelfCalWarning
    from selfcal.export.compensate import compensated_ik as compensated_ik
    from selfcal.export.compensate import solve_compensated_pose as solve_compensated_pose
    from selfcal.export.deploy import DeployedModel as DeployedModel
    from selfcal.export.deploy import deploy as deploy
    from selfcal.export.robot_toml import from_toml as from_toml
    from selfcal.export.robot_toml import to_toml as to_toml
    from selfcal.export.urdf import to_urdf as to_urdf
    from selfcal.importing.dataset import CameraImages as CameraImages
    from selfcal.importing.dataset import import_dataset as import_dataset
    from selfcal.importing.poses import import_pose_dataset as import_pose_dataset
    from selfcal.io.board_calibration import BoardCalibrationResult as BoardCalibrationResult
    from selfcal.io.calibration import CalibrationResult as CalibrationResult
    from selfcal.io.dataset import Dataset as Dataset
    from selfcal.io.dataset_info import DatasetError as DatasetError
    from selfcal.io.poses.dataset import PoseDataset as PoseDataset
    from selfcal.io.target_toml import load_target as load_target
    from selfcal.kinematics.ik_numeric import ToolTarget as ToolTarget
    from selfcal.robot.definition import RobotDef as RobotDef
    from selfcal.robot.definition import load_robot as load_robot
    from selfcal.sim.export_mjcf import calibrated_mjcf as calibrated_mjcf
    from selfcal.target.aruco import ArucoField as ArucoField
    from selfcal.target.base import Target as Target
    from selfcal.target.boards import AprilGrid as AprilGrid
    from selfcal.target.boards import Charuco as Charuco
    from selfcal.target.boards import Chessboard as Chessboard
    from selfcal.target.boards import CirclesGrid as CirclesGrid
    from selfcal.terms.probe import ProbeTerm as ProbeTerm
    from selfcal.terms.tracker import TrackerTerm as TrackerTerm
    from selfcal.threads import limit_threads as limit_threads
    from selfcal.threads import thread_count as thread_count

_PARTS: dict[str, tuple[str, ...]] = {
    # robots and datasets
    "selfcal.robot.definition": ("RobotDef", "load_robot"),
    "selfcal.importing.dataset": ("CameraImages", "import_dataset"),
    "selfcal.importing.poses": ("import_pose_dataset",),
    "selfcal.io.dataset": ("Dataset",),
    "selfcal.io.poses.dataset": ("PoseDataset",),
    # calibrating, evaluating, reading and writing (each dataset's route)
    "selfcal.calibration.routes": (
        "calibrate",
        "calibration_route",
        "dataset_route",
        "evaluate",
        "open_dataset",
        "read_calibration",
        "write_calibration",
    ),
    "selfcal.calibration.tracker.calibrate": ("TrackerRun", "calibrate_tracker"),
    "selfcal.calibration.tracker.identify": ("TrackerMeasurements", "identify_tracker"),
    "selfcal.calibration.tracker.drift": ("DriftCheck", "check_tracker"),
    "selfcal.calibration.drift.images": ("check_images",),
    "selfcal.calibration.drift.verdict": ("ImageDriftCheck",),
    "selfcal.terms.probe": ("ProbeTerm",),
    "selfcal.terms.tracker": ("TrackerTerm",),
    # results
    "selfcal.io.calibration": ("CalibrationResult",),
    "selfcal.io.board_calibration": ("BoardCalibrationResult",),
    "selfcal.calibration.handeye.calibrate": ("HandEyeCalibration",),
    "selfcal.calibration.handeye.calibration_file": ("HandEyeFile",),
    "selfcal.calibration.tracker.calibration_file": ("TrackerCalibration",),
    "selfcal.calibration.board.evaluate": ("Evaluation",),
    # using a calibration
    "selfcal.export.deploy": ("DeployedModel", "deploy"),
    "selfcal.export.compensate": ("compensated_ik", "solve_compensated_pose"),
    "selfcal.kinematics.ik_numeric": ("ToolTarget",),
    "selfcal.export.robot_toml": ("from_toml", "to_toml"),
    "selfcal.export.urdf": ("to_urdf",),
    "selfcal.sim.export_mjcf": ("calibrated_mjcf",),
    # camera models and targets
    "selfcal.camera": (
        "BrownConrady",
        "CameraModel",
        "DoubleSphere",
        "Fisheye",
        "Pinhole",
        "Rig",
        "camera_model",
    ),
    "selfcal.target.base": ("Target",),
    "selfcal.target.boards": ("AprilGrid", "Charuco", "Chessboard", "CirclesGrid"),
    "selfcal.target.aruco": ("ArucoField",),
    "selfcal.io.target_toml": ("load_target",),
    # errors and threads
    "selfcal.errors": (
        "EstimationError",
        "HardwareError",
        "InputError",
        "SelfCalError",
        "SelfCalWarning",
    ),
    "selfcal.io.dataset_info": ("DatasetError",),
    "selfcal.calibration.field.calibrate": ("CalibrationFailedError",),
    "selfcal.threads": ("limit_threads", "thread_count"),
}
_WHERE: dict[str, str] = {name: module for module, names in _PARTS.items() for name in names}

__all__ = [
    "AprilGrid",
    "ArucoField",
    "BoardCalibrationResult",
    "BrownConrady",
    "CalibrationFailedError",
    "CalibrationResult",
    "CameraImages",
    "CameraModel",
    "Charuco",
    "Chessboard",
    "CirclesGrid",
    "Dataset",
    "DatasetError",
    "DeployedModel",
    "DoubleSphere",
    "DriftCheck",
    "EstimationError",
    "Evaluation",
    "Fisheye",
    "HandEyeCalibration",
    "HandEyeFile",
    "HardwareError",
    "ImageDriftCheck",
    "InputError",
    "Pinhole",
    "PoseDataset",
    "ProbeTerm",
    "Rig",
    "RobotDef",
    "SelfCalError",
    "SelfCalWarning",
    "Target",
    "ToolTarget",
    "TrackerCalibration",
    "TrackerMeasurements",
    "TrackerRun",
    "TrackerTerm",
    "calibrate",
    "calibrate_tracker",
    "calibrated_mjcf",
    "calibration_route",
    "camera_model",
    "check_images",
    "check_tracker",
    "compensated_ik",
    "dataset_route",
    "deploy",
    "evaluate",
    "from_toml",
    "identify_tracker",
    "import_dataset",
    "import_pose_dataset",
    "limit_threads",
    "load_robot",
    "load_target",
    "open_dataset",
    "read_calibration",
    "solve_compensated_pose",
    "thread_count",
    "to_toml",
    "to_urdf",
    "write_calibration",
]


if not TYPE_CHECKING:  # hidden from mypy, which then checks every name against the imports above

    def __getattr__(name: str) -> object:
        """A public name, imported from its module on first use (then kept here)."""
        module = _WHERE.get(name)
        if module is None:
            raise AttributeError(f"module 'selfcal' has no attribute {name!r}")
        import importlib  # here: `import selfcal` itself imports nothing

        value = getattr(importlib.import_module(module), name)
        globals()[name] = value
        return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
