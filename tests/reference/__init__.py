"""Independent reference implementations used only by the test-suite (iDynTree-based, no Pinocchio)."""
