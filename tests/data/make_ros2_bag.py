"""Writes a ROS 2 bag (.mcap) from image files with the official writer (mcap-ros2-support).

The cross-check of vofront's bag reader against bags it did not write itself:

  PY=$(/work/shared/tools/peers/setup.sh)
  # KITTI odometry folder: image_0/ as mono8 Image + CameraInfo (P0), stamps from times.txt;
  # --stereo adds image_1/ as /right/image_raw with its CameraInfo (P1, the baseline).
  $PY tests/data/make_ros2_bag.py kitti ../shared/data/kitti_06 /tmp/kitti_06.mcap [--stereo]
  # A long bag: the clip's frames N times over (stamps continue), as a long recording:
  $PY tests/data/make_ros2_bag.py kitti ../shared/data/kitti_06 /tmp/long.mcap --repeat 20
  # Image files as CompressedImage png (the files' bytes), a CameraInfo from --camera,
  # frame i at i / fps seconds; --depth: 16-bit depth png files as CompressedImage png on
  # /camera/depth/compressed (read with --depth-topic and --depth-scale).
  $PY tests/data/make_ros2_bag.py png /tmp/tum_pair.mcap img_prev.png img_curr.png \
      --camera 517.3,516.5,318.6,255.3 --dist 0.2624,-0.9531,-0.0054,0.0026,1.1633 --fps 30 \
      --depth dep_prev.png dep_curr.png

Messages are CDR little-endian as the writer chooses; chunks are zstd-compressed (its default),
or `--compression lz4` (as many `ros2 bag record` setups write them) or `none`.
"""

import argparse
import pathlib

from mcap.writer import CompressionType
from mcap_ros2.writer import Writer
from PIL import Image as PilImage

HEADER = """
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
IMAGE = (
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
    "uint8 is_bigendian\nuint32 step\nuint8[] data\n" + HEADER
)
COMPRESSED = "std_msgs/Header header\nstring format\nuint8[] data\n" + HEADER
CAMERA_INFO = (
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
    "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
    "uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n" + HEADER + """
================================================================================
MSG: sensor_msgs/RegionOfInterest
uint32 x_offset
uint32 y_offset
uint32 height
uint32 width
bool do_rectify
"""
)


def header(ns, frame_id="camera"):
    return {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": frame_id}


def camera_info(ns, size, fx, fy, cx, cy, dist, tx=0.0):
    w, h = size
    return {
        "header": header(ns),
        "height": h,
        "width": w,
        "distortion_model": "plumb_bob",
        "d": list(dist),
        "k": [fx, 0, cx, 0, fy, cy, 0, 0, 1],
        "r": [1, 0, 0, 0, 1, 0, 0, 0, 1],
        "p": [fx, 0, cx, tx, 0, fy, cy, 0, 0, 0, 1, 0],
        "binning_x": 0,
        "binning_y": 0,
        "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False},
    }


def mono8(ns, path):
    img = PilImage.open(path).convert("L")
    w, h = img.size
    return {
        "header": header(ns),
        "height": h,
        "width": w,
        "encoding": "mono8",
        "is_bigendian": 0,
        "step": w,
        "data": img.tobytes(),
    }, (w, h)


def projection(calib, key):
    for line in calib.read_text().splitlines():
        if line.startswith(key + ":"):
            return [float(v) for v in line.split()[1:]]
    raise SystemExit(f"{calib}: no {key}")


def writer(f, args):
    compression = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
    return Writer(f, compression=compression[args.compression])


def kitti(args):
    root = pathlib.Path(args.folder)
    times = [float(t) for t in (root / "times.txt").read_text().split()]
    p0 = projection(root / "calib.txt", "P0")
    p1 = projection(root / "calib.txt", "P1")
    period = (times[-1] - times[0]) / max(len(times) - 1, 1)
    span = times[-1] - times[0] + period
    with open(args.out, "wb") as f:
        w = writer(f, args)
        s_img, s_info = w.register_msgdef("sensor_msgs/msg/Image", IMAGE), w.register_msgdef(
            "sensor_msgs/msg/CameraInfo", CAMERA_INFO
        )
        sides = [("/camera", "image_0", p0)] + ([("/right", "image_1", p1)] if args.stereo else [])
        for r, (i, t) in ((r, it) for r in range(args.repeat) for it in enumerate(times)):
            ns = round((t + r * span) * 1e9)
            for ns_name, folder, p in sides:
                msg, size = mono8(ns, root / folder / f"{i:06d}.png")
                w.write_message(f"{ns_name}/image_raw", s_img, msg, log_time=ns, publish_time=ns)
                info = camera_info(ns, size, p[0], p[5], p[2], p[6], [0.0] * 5, tx=p[3])
                w.write_message(f"{ns_name}/camera_info", s_info, info, log_time=ns, publish_time=ns)
        w.finish()


def png(args):
    fx, fy, cx, cy = [float(v) for v in args.camera.split(",")]
    dist = [float(v) for v in args.dist.split(",")] if args.dist else [0.0] * 5
    with open(args.out, "wb") as f:
        w = writer(f, args)
        s_img = w.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED)
        s_info = w.register_msgdef("sensor_msgs/msg/CameraInfo", CAMERA_INFO)
        depths = args.depth or []
        for i, path in enumerate(args.images):
            ns = round(i / args.fps * 1e9)
            size = PilImage.open(path).size
            msg = {"header": header(ns), "format": "png", "data": pathlib.Path(path).read_bytes()}
            w.write_message("/camera/image_raw/compressed", s_img, msg, log_time=ns, publish_time=ns)
            if i < len(depths):
                msg = {"header": header(ns), "format": "png", "data": pathlib.Path(depths[i]).read_bytes()}
                w.write_message("/camera/depth/compressed", s_img, msg, log_time=ns, publish_time=ns)
            info = camera_info(ns, size, fx, fy, cx, cy, dist)
            w.write_message("/camera/camera_info", s_info, info, log_time=ns, publish_time=ns)
        w.finish()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="mode", required=True)
    k = sub.add_parser("kitti")
    k.add_argument("folder")
    k.add_argument("out")
    k.add_argument("--stereo", action="store_true")
    k.add_argument("--repeat", type=int, default=1, help="write the clip's frames N times over")
    p = sub.add_parser("png")
    p.add_argument("out")
    p.add_argument("images", nargs="+")
    p.add_argument("--camera", required=True, help="fx,fy,cx,cy")
    p.add_argument("--dist", help="k1,k2,p1,p2,k3 (plumb_bob)")
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--depth", nargs="+", help="16-bit depth png files, one per image")
    for parser in (k, p):
        parser.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd")
    args = ap.parse_args()
    kitti(args) if args.mode == "kitti" else png(args)


if __name__ == "__main__":
    main()
