"""ROS bags in and out: the one bag reader and writer, the rest test, bag -> dataset
and dataset -> bag."""
