"""Rod deployment: discrete elastic rods, optimal grasp, neural controller, planning and pattern perception."""
