"""Reading frames (videos, image folders) and dev sets with ground truth; writing results as they are computed."""

from ._devset import DevSequence as DevSequence
from ._devset import Truth as Truth
from ._devset import load_devset as load_devset
from ._devset import load_truth as load_truth
from ._frames import Frame as Frame
from ._frames import FrameSource as FrameSource
from ._frames import open_frames as open_frames
from ._pose import parse_pose as parse_pose
from ._pose import pose_to_dict as pose_to_dict
from ._results import ResultWriter as ResultWriter
from ._results import read_angles_csv as read_angles_csv

__all__ = ["Frame", "FrameSource", "open_frames", "ResultWriter", "read_angles_csv", "parse_pose", "pose_to_dict",
           "load_devset", "load_truth", "DevSequence", "Truth"]
