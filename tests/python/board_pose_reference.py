"""An independent OpenCV computation of a board's pose (Python bindings).

Usage: board_pose_reference.py REQUEST.json

REQUEST holds: "image" (path), "dictionary" (an OpenCV predefined name such
as "DICT_6X6_250", or the path of a dictionary file as read by
Dictionary::readDictionary), "board" (slidetrack's board layout: {"kind":
"grid", markers_x, markers_y, marker_length_m, separation_m, first_id} or
{"kind": "charuco", squares_x, squares_y, square_length_m,
marker_length_m}), "camera" (an OpenCV YAML file with camera_matrix and
distortion_coefficients) and "given": the points slidetrack used, as
{"ids": [...], "image_px": [[u, v], ...]} (a GridBoard's marker ids, one per
four corners in OpenCV's corner order; a ChArUco board's corner ids, one per
corner; optional).

Prints JSON with two poses of the board frame in the camera frame (rvec,
tvec in m, RMS reprojection error in px, points used), each found with
cv2.solvePnP (SOLVEPNP_ITERATIVE) then cv2.solvePnPRefineLM:
- "given": from the given image points, matched to the object points of
  cv2's own board object (GridBoard.getObjPoints / getIds,
  CharucoBoard.getChessboardCorners);
- "own": from cv2's own detection (ArucoDetector with default parameters;
  for ChArUco the CharucoDetector with the camera), through
  Board.matchImagePoints; with the detected marker corners and ChArUco
  corners (these moved by -0.5 px: see below).

OpenCV returns ChArUco corners half a pixel right of and below the
convention of its marker corners and of camera intrinsics (pixel centres at
integers): it refines each at corner - 0.5 px and adds 0.5 px back
(opencv_contrib 4.6.0 modules/aruco/src/charuco.cpp, kept in objdetect).
Like slidetrack, this script subtracts 0.5 px from them.

The board frame of cv2 (OpenCV >= 4.7, objdetect) is the one of OpenCV 4.6's
aruco module that slidetrack follows: origin at the board's top-left corner,
x right, y down the print, z into it.
"""
import json
import sys

import cv2
import numpy as np


def dictionary(spec):
    if spec.startswith("DICT_"):
        return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, spec))
    fs = cv2.FileStorage(spec, cv2.FILE_STORAGE_READ)
    d = cv2.aruco.Dictionary()
    assert d.readDictionary(fs.root()), f"{spec}: not a dictionary file"
    return d


def board(layout, d):
    if layout["kind"] == "grid":
        n = layout["markers_x"] * layout["markers_y"]
        ids = np.arange(layout.get("first_id", 0), layout.get("first_id", 0) + n, dtype=np.int32)
        return cv2.aruco.GridBoard(
            (layout["markers_x"], layout["markers_y"]),
            layout["marker_length_m"],
            layout["separation_m"],
            d,
            ids,
        )
    b = cv2.aruco.CharucoBoard(
        (layout["squares_x"], layout["squares_y"]), layout["square_length_m"], layout["marker_length_m"], d
    )
    # OpenCV 4.6's pattern (no change for an odd number of rows).
    b.setLegacyPattern(layout["squares_y"] % 2 == 0)
    return b


def camera(path):
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
    k = fs.getNode("camera_matrix").mat()
    dist = fs.getNode("distortion_coefficients").mat().reshape(-1)
    return k, dist


def pose(obj, img, k, dist):
    obj = np.asarray(obj, dtype=np.float64).reshape(-1, 3)
    img = np.asarray(img, dtype=np.float64).reshape(-1, 2)
    ok, rvec, tvec = cv2.solvePnP(obj, img, k, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    assert ok, "solvePnP failed"
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, k, dist, rvec, tvec)
    projected, _ = cv2.projectPoints(obj, rvec, tvec, k, dist)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - img) ** 2, axis=1))))
    return {"rvec": rvec.reshape(-1).tolist(), "tvec_m": tvec.reshape(-1).tolist(), "rms_px": rms, "points": len(obj)}


def given_object_points(layout, b, ids):
    if layout["kind"] == "grid":
        board_ids = list(b.getIds().reshape(-1))
        objs = b.getObjPoints()
        return [p for i in ids for p in np.asarray(objs[board_ids.index(i)]).reshape(4, 3)]
    corners = np.asarray(b.getChessboardCorners()).reshape(-1, 3)
    return [corners[i] for i in ids]


def own(layout, b, d, image, k, dist):
    corners, ids, _ = cv2.aruco.ArucoDetector(d, cv2.aruco.DetectorParameters()).detectMarkers(image)
    markers = {int(i): c.reshape(4, 2).tolist() for i, c in zip(ids.reshape(-1), corners)}
    out = {"markers": markers}
    if layout["kind"] == "grid":
        obj, img = b.matchImagePoints(corners, ids)
    else:
        params = cv2.aruco.CharucoParameters()
        params.cameraMatrix = k
        params.distCoeffs = dist
        detector = cv2.aruco.CharucoDetector(b, params, cv2.aruco.DetectorParameters())
        ch_corners, ch_ids, _, _ = detector.detectBoard(image, markerCorners=corners, markerIds=ids)
        # OpenCV refines each ChArUco corner at corner - 0.5 px and returns it
        # + 0.5 px (charuco.cpp); back to the markers' convention (pixel
        # centres at integers), as slidetrack does.
        ch_corners = ch_corners - 0.5
        out["charuco"] = {int(i): c.reshape(2).tolist() for i, c in zip(ch_ids.reshape(-1), ch_corners)}
        obj, img = b.matchImagePoints(ch_corners, ch_ids)
    out["pose"] = pose(obj, img, k, dist)
    return out


def main():
    request = json.load(open(sys.argv[1]))
    layout = request["board"]
    d = dictionary(request["dictionary"])
    b = board(layout, d)
    k, dist = camera(request["camera"])
    image = cv2.imread(request["image"], cv2.IMREAD_COLOR)
    assert image is not None, f"{request['image']}: cannot read"
    result = {"opencv": cv2.__version__, "own": own(layout, b, d, image, k, dist)}
    given = request.get("given")
    if given is not None:
        obj = given_object_points(layout, b, given["ids"])
        result["given"] = pose(obj, given["image_px"], k, dist)
    json.dump(result, sys.stdout)


if __name__ == "__main__":
    main()
