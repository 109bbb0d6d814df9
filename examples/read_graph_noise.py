# Reading a graph file with its noise convention explicit, and what a real-data read skipped.
import probslam
from probslam.graph import read_pose_graph, read_pose_graph_with_report

path = probslam.data.path("victoria_park_1000.txt")           # iSAM text: square-root information
g = read_pose_graph(path, "isam", noise="sqrt_information")   # the same as noise="default" here
read = read_pose_graph_with_report(path)                       # rows="skip"
print(read.graph, read.report.skipped_rows, read.report.skipped_lines)
