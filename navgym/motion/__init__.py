"""Truth helpers shared by the platforms: smooth motion profiles and the 3-D trajectory container."""
