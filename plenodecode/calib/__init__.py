"""plenodecode.calib"""
